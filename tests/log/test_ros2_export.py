"""``cosim export --ros2``: every message read back by two decoders and held to the source log.

The bag is read with rosbags (``AnyReader``, which builds its types from the bag's own
schemas) and with mcap-ros2-support's decoder (``mcap_ros2.decoder``, an independent CDR and
``ros2msg`` implementation); each decoded message is compared field by field with the source
message of the run log (JSON), to float64 precision, and float32 for the Ackermann command.
"""

from __future__ import annotations

import math
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.writer import Writer
from mcap_ros2.decoder import DecoderFactory
from rosbags.highlevel import AnyReader

from cosim.cli import main
from cosim.log.reader import iter_topics, read_summary
from cosim.log.ros2.messages import UNKNOWN_VARIANCE
from cosim.simulation.runner import RunResult

SOURCES = ("/vehicle/truth", "/vehicle/estimate", "/sensors/imu", "/sensors/gnss",
           "/gnss/fix", "/control/command", "/reference/path")


def euler(q: Any) -> tuple[float, float, float]:
    """Roll, pitch, yaw of a unit quaternion (Z-Y-X), written out independently."""
    roll = math.atan2(2 * (q.w * q.x + q.y * q.z), 1 - 2 * (q.x**2 + q.y**2))
    pitch = math.asin(max(-1.0, min(1.0, 2 * (q.w * q.y - q.z * q.x))))
    yaw = math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y**2 + q.z**2))
    return roll, pitch, yaw


def stamp_ns(header: Any) -> int:
    return header.stamp.sec * 1_000_000_000 + header.stamp.nanosec


def rosbags_messages(bag: Path) -> dict[str, list[tuple[int, Any]]]:
    out: dict[str, list[tuple[int, Any]]] = {}
    with AnyReader([bag]) as reader:  # types from the bag's own schemas
        for connection, log_time, raw in reader.messages():
            out.setdefault(connection.topic, []).append(
                (log_time, reader.deserialize(raw, connection.msgtype)))
    return out


def mcap_ros2_messages(bag: Path) -> dict[str, list[tuple[int, Any]]]:
    out: dict[str, list[tuple[int, Any]]] = {}
    with open(bag, "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        assert reader.get_header().profile == "ros2"
        for schema, channel, message, decoded in reader.iter_decoded_messages(
                log_time_order=False):
            assert (channel.message_encoding, schema.encoding) == ("cdr", "ros2msg")
            assert "offered_qos_profiles" in channel.metadata  # the ros2 profile's user data
            out.setdefault(channel.topic, []).append((message.log_time, decoded))
    return out


def source_messages(log: Path) -> dict[str, list[tuple[int, dict[str, Any]]]]:
    epoch = read_summary(log).epoch_ns
    out: dict[str, list[tuple[int, dict[str, Any]]]] = {}
    for topic, t_ns, message in iter_topics(log, set(SOURCES)):
        out.setdefault(topic, []).append((epoch + t_ns, message))
    return out


def nan_if_null(value: Any) -> float:
    return math.nan if value is None else float(value)


def check_truth(odometry: Any, transforms: Any, truth: dict[str, Any]) -> None:
    pose = odometry.pose.pose
    assert (pose.position.x, pose.position.y, pose.position.z) == \
        (truth["x_m"], truth["y_m"], truth["z_m"])
    assert euler(pose.orientation) == pytest.approx(
        (truth["roll_rad"], truth["pitch_rad"], truth["yaw_rad"]), abs=1e-12)
    twist = odometry.twist.twist
    assert (twist.linear.x, twist.linear.y, twist.angular.z) == \
        (truth["vx_mps"], truth["vy_mps"], truth["yaw_rate_radps"])
    assert not np.any(odometry.pose.covariance) and not np.any(odometry.twist.covariance)
    assert (odometry.header.frame_id, odometry.child_frame_id) == ("world", "base_link")
    (transform,) = transforms.transforms
    assert (transform.header.frame_id, transform.child_frame_id) == ("world", "base_link")
    t = transform.transform
    assert (t.translation.x, t.translation.y, t.translation.z) == \
        (truth["x_m"], truth["y_m"], truth["z_m"])
    assert (t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w) == (
        pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w)


def check_estimate(odometry: Any, estimate: dict[str, Any]) -> None:
    names = estimate["state_names"]
    n = len(names)
    covariance = np.array([nan_if_null(c) for c in estimate["covariance"]]).reshape(n, n)
    pose, twist = odometry.pose.pose, odometry.twist.twist
    assert (pose.position.x, pose.position.y) == (estimate["x_m"], estimate["y_m"])
    roll, pitch, yaw = euler(pose.orientation)
    assert (roll, pitch, yaw) == pytest.approx((estimate["roll_rad"], 0.0, estimate["yaw_rad"]),
                                               abs=1e-12)
    assert (twist.linear.x, twist.linear.y, twist.angular.x, twist.angular.z) == (
        estimate["vx_mps"], estimate["vy_mps"], estimate["roll_rate_radps"],
        estimate["yaw_rate_radps"])
    for rows, matrix in (((0, 1, None, 8, None, 2), odometry.pose.covariance),
                         ((3, 4, None, 9, None, 5), odometry.twist.covariance)):
        # rows: the EKF's index of x, y, z, roll, pitch, yaw (pose) and vx, vy, vz, roll
        # rate, pitch rate, yaw rate (twist) in estimation.state.STATE_NAMES
        m = np.asarray(matrix, dtype=float).reshape(6, 6)
        for i, a in enumerate(rows):
            for j, b in enumerate(rows):
                if a is not None and b is not None:
                    assert m[i, j] == covariance[a, b]
                else:
                    assert m[i, j] == (UNKNOWN_VARIANCE if i == j else 0.0)


def check_imu(imu: Any, measurement: dict[str, Any]) -> None:
    gyro_sigma, ax_sigma, ay_sigma = measurement["sigma"]
    assert imu.angular_velocity.z == measurement["yaw_rate_radps"]
    assert (imu.linear_acceleration.x, imu.linear_acceleration.y) == \
        (measurement["ax_mps2"], measurement["ay_mps2"])
    assert imu.orientation_covariance[0] == -1.0  # no orientation
    assert imu.angular_velocity_covariance[8] == gyro_sigma**2
    assert imu.linear_acceleration_covariance[0] == ax_sigma**2
    assert imu.linear_acceleration_covariance[4] == ay_sigma**2
    assert imu.angular_velocity_covariance[0] == UNKNOWN_VARIANCE


def check_fix(fix: Any, foxglove_fix: dict[str, Any]) -> None:
    """Against the log's own ``/gnss/fix`` (foxglove.LocationFix, written during the run)."""
    assert (fix.latitude, fix.longitude, fix.altitude) == (
        foxglove_fix["latitude"], foxglove_fix["longitude"], foxglove_fix["altitude"])
    assert list(fix.position_covariance) == foxglove_fix["position_covariance"]
    assert (fix.status.status, fix.position_covariance_type) == (0, 2)


def check_command(stamped: Any, command: dict[str, Any]) -> None:
    drive = stamped.drive
    assert drive.steering_angle == np.float32(command["steer_rad"])
    assert drive.acceleration == np.float32(command["accel_mps2"])
    assert math.isnan(drive.speed)  # cosim commands an acceleration, not a speed


def check_path(path: Any, reference: dict[str, Any]) -> None:
    assert [p.pose.position.x for p in path.poses] == reference["x_m"]
    assert [p.pose.position.y for p in path.poses] == reference["y_m"]
    yaws = [euler(p.pose.orientation)[2] for p in path.poses]
    assert yaws == pytest.approx(reference["yaw_rad"], abs=1e-12)


CHECKS: tuple[tuple[str, str, Callable[[Any, dict[str, Any]], None]], ...] = (
    # (ROS 2 topic, source topic, check of one decoded message against its source message)
    ("/vehicle/estimate", "/vehicle/estimate", check_estimate),
    ("/sensors/imu", "/sensors/imu", check_imu),
    ("/sensors/gnss", "/gnss/fix", check_fix),
    ("/control/command", "/control/command", check_command),
    ("/reference/path", "/reference/path", check_path),
)


@pytest.fixture(scope="module")
def exported(short_run: RunResult, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("ros2") / "bag.mcap"
    assert main(["export", "--ros2", str(short_run.log_path), "--out", str(out)]) == 0
    return out


@pytest.mark.parametrize("decode", [rosbags_messages, mcap_ros2_messages],
                         ids=["rosbags", "mcap-ros2-support"])
def test_every_message_reads_back_equal_to_the_source_log(
        decode: Callable[[Path], dict[str, list[tuple[int, Any]]]], exported: Path,
        short_run: RunResult) -> None:
    bag, source = decode(exported), source_messages(short_run.log_path)
    assert set(bag) == {"/vehicle/truth", "/tf", "/vehicle/estimate", "/sensors/imu",
                        "/sensors/gnss", "/control/command", "/reference/path"}
    truths = source["/vehicle/truth"]
    assert len(bag["/vehicle/truth"]) == len(bag["/tf"]) == len(truths) > 100
    for (t_odom, odometry), (t_tf, transforms), (t_ns, truth) in zip(
            bag["/vehicle/truth"], bag["/tf"], truths, strict=True):
        assert t_odom == t_tf == t_ns == stamp_ns(odometry.header)
        check_truth(odometry, transforms, truth)
    for topic, source_topic, check in CHECKS:
        pairs = list(zip(bag[topic], source[source_topic], strict=True))
        assert pairs, topic
        for (log_time, message), (t_ns, original) in pairs:
            assert log_time == t_ns == stamp_ns(message.header), topic
            check(message, original)


def test_the_stamps_are_the_simulated_epoch(exported: Path) -> None:
    first = next(iter(rosbags_messages(exported)["/vehicle/truth"]))[1]
    assert (first.header.stamp.sec, first.header.stamp.nanosec) == (1767225600, 0)  # 2026-01-01


def test_the_ackermann_definition_travels_with_the_bag(exported: Path) -> None:
    with open(exported, "rb") as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None
    schema = next(s for s in summary.schemas.values()
                  if s.name == "ackermann_msgs/msg/AckermannDriveStamped")
    assert schema.encoding == "ros2msg"
    text = schema.data.decode()
    assert "MSG: ackermann_msgs/AckermannDrive\nfloat32 steering_angle\n" in text
    assert "float32 acceleration" in text


def test_a_truncated_log_exports_its_complete_part(short_run: RunResult, tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    cut = tmp_path / "cut.mcap"
    data = short_run.log_path.read_bytes()
    cut.write_bytes(data[: len(data) // 2])
    out = tmp_path / "cut-ros2.mcap"
    assert main(["export", "--ros2", str(cut)]) == 0
    assert "was cut off" in capsys.readouterr().err
    bag, source = rosbags_messages(out), source_messages(cut)
    assert 0 < len(bag["/vehicle/truth"]) == len(source["/vehicle/truth"]) < 201
    for (_, odometry), (_, truth) in zip(bag["/vehicle/truth"], source["/vehicle/truth"],
                                         strict=True):
        assert odometry.pose.pose.position.x == truth["x_m"]


def refused(args: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    assert main(args) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    return err


def test_an_existing_out_is_never_replaced_without_force(
        short_run: RunResult, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "mine.mcap"
    out.write_bytes(b"the user's earlier bag")
    args = ["export", "--ros2", str(short_run.log_path), "--out", str(out)]
    assert "exists; expected a new file name (or --force" in refused(args, capsys)
    assert out.read_bytes() == b"the user's earlier bag"
    assert main([*args, "--force"]) == 0
    assert rosbags_messages(out)["/vehicle/truth"]
    assert not list(tmp_path.glob(".*partial"))


def test_missing_foreign_and_own_inputs_are_one_line(
        short_run: RunResult, exported: Path, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    assert "no such file (expected the MCAP log of a cosim run)" in refused(
        ["export", "--ros2", str(tmp_path / "none.mcap")], capsys)
    foreign = tmp_path / "foreign.mcap"
    with open(foreign, "wb") as stream:
        writer = Writer(stream)
        writer.start(profile="", library="someone else")
        schema = writer.register_schema("x", "jsonschema", b"{}")
        channel = writer.register_channel("/points", "json", schema)
        writer.add_message(channel, 0, b"{}", 0)
        writer.finish()
    assert "not a run log (written by 'someone else'" in refused(
        ["export", "--ros2", str(foreign), "--out", str(tmp_path / "a.mcap")], capsys)
    assert "not a run log (written by 'cosim" in refused(
        ["export", "--ros2", str(exported), "--out", str(tmp_path / "b.mcap")], capsys)
    copy = tmp_path / "run.mcap"
    shutil.copyfile(short_run.log_path, copy)
    assert "is the input file" in refused(
        ["export", "--ros2", str(copy), "--out", str(copy), "--force"], capsys)
    assert copy.read_bytes() == short_run.log_path.read_bytes()
    assert not (tmp_path / "a.mcap").exists() and not (tmp_path / "b.mcap").exists()


def test_a_fix_without_a_position_is_no_fix() -> None:
    from cosim.log.foxglove import GeoOrigin
    from cosim.log.ros2.messages import RosMessages
    from cosim.log.ros2.types import typestore

    build = RosMessages(typestore(), GeoOrigin())
    fix = build.nav_sat_fix(0, {"t_s": 0.0, "sensor": "gnss", "x_m": None, "y_m": None,
                                "sigma": [0.5, 0.5]})
    assert fix.status.status == -1 and math.isnan(fix.latitude) and math.isnan(fix.longitude)
    ok = build.nav_sat_fix(0, {"t_s": 0.0, "sensor": "gnss", "x_m": 0.0, "y_m": 0.0,
                               "sigma": [0.5, 0.5]})
    assert ok.status.status == 0 and ok.position_covariance[0] == 0.25


def test_an_older_logs_planar_truth_exports_with_zeros_and_no_truth_is_refused() -> None:
    """A log written before the truth had z_m, roll and pitch: exported as 0 (the export
    says so once); a message without x_m is no cosim truth: one clear error."""
    from cosim.core.exceptions import CosimError
    from cosim.log.ros2.messages import planar_fields_missing, truth_numbers

    older = {"t_s": 1.0, "x_m": 3.0, "y_m": 4.0, "yaw_rad": 0.1, "vx_mps": 10.0,
             "vy_mps": 0.2, "yaw_rate_radps": 0.05}
    v = truth_numbers(older)
    assert (v["z_m"], v["roll_rad"], v["pitch_rad"]) == (0.0, 0.0, 0.0) and v["x_m"] == 3.0
    assert planar_fields_missing(older) == ["z_m", "roll_rad", "pitch_rad"]
    with pytest.raises(CosimError, match="/vehicle/truth without x_m"):
        truth_numbers({k: v for k, v in older.items() if k != "x_m"})


def test_an_export_holds_its_out_as_a_run_does(short_run: RunResult, tmp_path: Path) -> None:
    """--force onto a file another run or export is writing silently replaced it; the
    output is now held for the export, and a second writer is refused."""
    from cosim.core.exceptions import CosimError
    from cosim.log.output_claim import claim_output
    from cosim.log.ros2.bag import export_ros2

    out = tmp_path / "busy.mcap"
    with claim_output(out, "--out", False, []):  # a run writing it now
        with pytest.raises(CosimError, match="another cosim run is writing it now"):
            export_ros2(short_run.log_path, out, force=True)
    assert export_ros2(short_run.log_path, out).path == out  # free again
