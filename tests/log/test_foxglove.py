"""Foxglove messages: frames, the map fix, the per-step 3D scene, and the shipped layout."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import mujoco
import numpy as np
import pytest

from cosim.core.records import Estimate, Plan, VehicleState
from cosim.core.vehicle_params import VehicleParams
from cosim.log import foxglove
from cosim.log.reader import iter_messages, iter_topics, read_summary
from cosim.simulation.runner import RunResult
from tests.conftest import run_scenario

LAYOUT = Path(__file__).resolve().parents[2] / "examples" / "foxglove-layout.json"
SCENE_TOPICS = ("/scene", "/scene/car", "/scene/plan", "/scene/estimate")


def _rotate(q: dict[str, float], v: np.ndarray) -> np.ndarray:
    """Rotate vector ``v`` by unit quaternion ``q``."""
    u = np.array([q["x"], q["y"], q["z"]])
    return v + 2.0 * np.cross(u, np.cross(u, v) + q["w"] * v)


def _vec(d: dict[str, float]) -> np.ndarray:
    return np.array([d["x"], d["y"], d["z"]])


def _truth(steer_rad: float = 0.0) -> VehicleState:
    return VehicleState(t_s=1.25, x_m=10.0, y_m=2.0, z_m=0.55, roll_rad=0.01,
                        pitch_rad=-0.02, yaw_rad=0.3, vx_mps=15.0, vy_mps=0.0,
                        yaw_rate_radps=0.0, ax_mps2=0.0, ay_mps2=0.0, steer_rad=steer_rad,
                        wheel_speed_radps=(0.0, 0.0, 0.0, 0.0))


@pytest.mark.parametrize(("roll", "pitch", "yaw"),
                         [(0.0, 0.0, 0.0), (0.05, -0.03, 1.2), (-0.1, 0.2, -2.9)])
def test_frame_transform_rotation_is_the_plants_quaternion(roll: float, pitch: float,
                                                           yaw: float) -> None:
    q = foxglove.quaternion_from_euler(roll, pitch, yaw)
    reference = np.empty(4)  # MuJoCo's own intrinsic z-y'-x'' conversion
    mujoco.mju_euler2Quat(reference, np.array([yaw, pitch, roll]), "zyx")
    assert [q["w"], q["x"], q["y"], q["z"]] == pytest.approx(list(reference), abs=1e-12)


def test_frame_transform_puts_base_link_at_the_cog_with_its_heading() -> None:
    message = foxglove.frame_transform(_truth())
    assert (message["parent_frame_id"], message["child_frame_id"]) == ("world", "base_link")
    assert _vec(message["translation"]) == pytest.approx([10.0, 2.0, 0.55])
    forward = _rotate(message["rotation"], np.array([1.0, 0.0, 0.0]))
    assert math.atan2(forward[1], forward[0]) == pytest.approx(0.3, abs=1e-3)
    assert message["timestamp"] == {"sec": 1, "nsec": 250_000_000}


def test_location_fix_uses_the_wgs84_radii_of_curvature() -> None:
    """At 45 deg latitude one degree of latitude is 111 131.78 m and one degree of
    longitude 78 846.8 m (WGS-84; the series 111 132.954 - 559.822 cos 2phi + 1.175 cos 4phi
    and 111 412.84 cos phi - 93.5 cos 3phi + 0.118 cos 5phi)."""
    origin = foxglove.GeoOrigin(latitude_deg=45.0, longitude_deg=7.0, altitude_m=300.0)
    north = foxglove.location_fix(0.0, 1000.0, 0.0, 0.02, origin)
    east = foxglove.location_fix(1000.0, 0.0, 0.0, 0.02, origin)
    assert north["latitude"] - 45.0 == pytest.approx(1000.0 / 111_131.78, rel=1e-6)
    assert north["longitude"] == 7.0
    assert east["longitude"] - 7.0 == pytest.approx(1000.0 / 78_846.8, rel=1e-6)
    assert east["altitude"] == 300.0
    assert north["position_covariance"][0] == pytest.approx(0.02**2)
    assert len(north["position_covariance"]) == 9


def test_covariance_ellipse_has_n_sigma_semi_axes_along_the_eigenvectors() -> None:
    angle = math.radians(30.0)
    rotation = np.array([[math.cos(angle), -math.sin(angle)],
                         [math.sin(angle), math.cos(angle)]])
    covariance = rotation @ np.diag([4.0, 1.0]) @ rotation.T  # sigmas 2 m and 1 m
    ellipse = foxglove.covariance_ellipse(covariance, 3.0)
    assert ellipse.semi_major_m == pytest.approx(6.0)
    assert ellipse.semi_minor_m == pytest.approx(3.0)
    assert math.tan(ellipse.angle_rad) == pytest.approx(math.tan(angle))


def test_covariance_ellipse_is_lapacks_eigendecomposition() -> None:
    # The closed form against numpy's eigh: the semi-axes to rounding, the major axis along
    # the larger eigenvector (parallel: an ellipse turned by pi is the same), over shapes
    # from a circle to a line. It fails with the axes swapped, the angle not halved or
    # ``atan2(b, a - c)``.
    rng = np.random.default_rng(3)
    for _ in range(500):
        sigma = rng.uniform(0.01, 3.0, size=2) * np.array([1.0, rng.choice([1e-4, 0.1, 1.0])])
        angle = rng.uniform(-math.pi, math.pi)
        rotation = np.array([[math.cos(angle), -math.sin(angle)],
                             [math.sin(angle), math.cos(angle)]])
        covariance = rotation @ np.diag(sigma**2) @ rotation.T
        ellipse = foxglove.covariance_ellipse(covariance, 2.0)
        eigenvalues, eigenvectors = np.linalg.eigh(covariance)
        assert ellipse.semi_major_m == pytest.approx(2.0 * math.sqrt(eigenvalues[1]), rel=1e-9)
        assert ellipse.semi_minor_m == pytest.approx(2.0 * math.sqrt(max(eigenvalues[0], 0.0)),
                                                     rel=1e-6, abs=1e-9)
        if eigenvalues[1] > 1.01 * eigenvalues[0]:
            major = eigenvectors[:, 1]
            along = (math.cos(ellipse.angle_rad), math.sin(ellipse.angle_rad))
            assert abs(along[0] * major[1] - along[1] * major[0]) < 1e-6
    # A line (a singular covariance) and a circle.
    line = foxglove.covariance_ellipse(np.array([[1.0, 1.0], [1.0, 1.0]]), 1.0)
    assert (line.semi_major_m, line.semi_minor_m) == (pytest.approx(math.sqrt(2.0)), 0.0)
    assert line.angle_rad == pytest.approx(math.pi / 4)
    circle = foxglove.covariance_ellipse(np.eye(2) * 0.25, 3.0)
    assert circle.semi_major_m == circle.semi_minor_m == 1.5


def test_car_scene_has_a_body_and_four_wheels_on_the_ground() -> None:
    params = VehicleParams()
    steer = 0.2
    scene = foxglove.car_scene(_truth(steer), params)
    (car,) = scene["entities"]
    assert (car["id"], car["frame_id"], car["frame_locked"]) == ("car", "base_link", True)
    assert len(car["cubes"]) == 2 and len(car["cylinders"]) == 4
    ground_z = -params.cog_height_m
    body = car["cubes"][0]
    assert body["pose"]["position"]["z"] - body["size"]["z"] / 2 > ground_z  # above ground
    assert body["size"]["x"] > params.wheelbase_m
    centres = [_vec(w["pose"]["position"]) for w in car["cylinders"]]
    expected = [(params.cog_front_m, params.track_m / 2), (params.cog_front_m, -params.track_m / 2),
                (-params.cog_rear_m, params.track_m / 2), (-params.cog_rear_m, -params.track_m / 2)]
    for centre, (x, y) in zip(centres, expected, strict=True):
        assert centre == pytest.approx([x, y, ground_z + params.wheel_radius_m])
    for wheel, wheel_steer in zip(car["cylinders"], (steer, steer, 0.0, 0.0), strict=True):
        assert wheel["size"]["x"] == pytest.approx(2 * params.wheel_radius_m)
        # A cylinder's axis is its local z: it must lie along the (steered) axle.
        axle = _rotate(wheel["pose"]["orientation"], np.array([0.0, 0.0, 1.0]))
        lateral = np.array([-math.sin(wheel_steer), math.cos(wheel_steer), 0.0])
        assert abs(axle @ lateral) == pytest.approx(1.0)


def _plan(state_names: tuple[str, ...], states: np.ndarray) -> Plan:
    return Plan(t_s=0.5, dt_s=0.05, state_names=state_names, states=states,
                input_names=("accel_mps2",), inputs=np.zeros((len(states) - 1, 1)), cost=0.0,
                solve_time_s=0.0, iterations=1, status="ok", success=True, fallback=False)


def test_plan_scene_draws_the_finite_predicted_positions() -> None:
    states = np.array([[0.0, 0.0], [1.0, 0.1], [np.nan, np.nan], [3.0, 0.3]])
    (entity,) = foxglove.plan_scene(_plan(("x_m", "y_m"), states))["entities"]
    assert (entity["id"], entity["frame_id"]) == ("plan", "world")
    (line,) = entity["lines"]
    assert [(p["x"], p["y"]) for p in line["points"]] == [(0.0, 0.0), (1.0, 0.1), (3.0, 0.3)]
    # Path-error coordinates (dynamic-mpc) have no world positions: no scene.
    assert foxglove.plan_scene(_plan(("e1_m", "e2_rad"), states)) is None


def test_estimate_scene_without_a_finite_position_is_empty() -> None:
    estimate = Estimate(0.0, ("x_m", "y_m", "yaw_rad"), np.array([np.nan, 0.0, 0.0]),
                        np.eye(3))
    (entity,) = foxglove.estimate_scene(estimate)["entities"]
    assert entity["id"] == "estimate"
    assert entity["arrows"] == [] and entity["spheres"] == []


def test_the_log_has_the_scene_topics_and_tracking_errors(short_run: RunResult) -> None:
    topics = {c.topic: c for c in read_summary(short_run.log_path).channels}
    for topic in SCENE_TOPICS:
        assert topics[topic].schema_name == "foxglove.SceneUpdate", topic
    assert topics["/scene"].message_count == 1  # static: Foxglove's seek keeps it
    # The 3D scenes at sim.scene_period_s (0.04 s), every fourth log tick (0.01 s).
    log_ticks = topics["/vehicle/truth"].message_count
    assert topics["/scene/car"].message_count == (log_ticks - 1) // 4 + 1
    assert topics["/scene/estimate"].message_count == topics["/scene/car"].message_count
    assert topics["/scene/plan"].message_count == topics["/control/plan"].message_count
    assert topics["/control/errors"].message_count == topics["/vehicle/truth"].message_count
    assert topics["/gnss/fix"].message_count == topics["/sensors/gnss"].message_count
    errors = [m for _, m in iter_messages(short_run.log_path, "/control/errors")]
    assert max(abs(m["cte_m"]) for m in errors) == pytest.approx(short_run.metrics["cte_max_m"])
    assert errors[0]["ref_speed_mps"] == pytest.approx(20.0)


def test_the_plan_line_is_the_predicted_path(short_run: RunResult) -> None:
    plans = dict(iter_messages(short_run.log_path, "/control/plan"))
    scenes = dict(iter_messages(short_run.log_path, "/scene/plan"))
    assert scenes.keys() == plans.keys()
    for t_ns, scene in scenes.items():
        (entity,) = scene["entities"]
        (line,) = entity["lines"]
        points = np.array([[p["x"], p["y"]] for p in line["points"]])
        predicted = np.column_stack([plans[t_ns]["predicted_x_m"], plans[t_ns]["predicted_y_m"]])
        assert points == pytest.approx(predicted, abs=1e-4)


def test_the_ellipse_axes_are_three_sigma_of_the_estimate(short_run: RunResult) -> None:
    estimates = dict(iter_messages(short_run.log_path, "/vehicle/estimate"))
    checked = 0
    for t_ns, scene in iter_messages(short_run.log_path, "/scene/estimate"):
        estimate = estimates[t_ns]
        names = estimate["state_names"]
        n = len(names)
        covariance = np.array(estimate["covariance"]).reshape(n, n)
        i, j = names.index("x_m"), names.index("y_m")
        sigmas = np.sqrt(np.linalg.eigvalsh(covariance[np.ix_([i, j], [i, j])]))
        (entity,) = scene["entities"]
        (ellipse,) = entity["spheres"]
        assert ellipse["size"]["x"] == pytest.approx(2 * 3 * sigmas[1], rel=1e-9)
        assert ellipse["size"]["y"] == pytest.approx(2 * 3 * sigmas[0], rel=1e-9)
        assert _vec(ellipse["pose"]["position"])[:2] == pytest.approx(
            [estimate["x_m"], estimate["y_m"]])
        (arrow,) = entity["arrows"]
        heading = _rotate(arrow["pose"]["orientation"], np.array([1.0, 0.0, 0.0]))
        assert math.atan2(heading[1], heading[0]) == pytest.approx(estimate["yaw_rad"],
                                                                   abs=1e-9)
        checked += 1
    assert checked == (len(estimates) - 1) // 4 + 1


def test_the_car_follows_the_true_steering(short_run: RunResult) -> None:
    truth = dict(iter_messages(short_run.log_path, "/vehicle/truth"))
    for t_ns, scene in iter_messages(short_run.log_path, "/scene/car"):
        (car,) = scene["entities"]
        front_left = car["cylinders"][0]
        axle = _rotate(front_left["pose"]["orientation"], np.array([0.0, 0.0, 1.0]))
        # The axle points to -y of the wheel: its heading is the steer angle - 90 deg.
        assert math.atan2(axle[1], axle[0]) + math.pi / 2 == pytest.approx(
            truth[t_ns]["steer_rad"], abs=1e-9)


def test_a_nan_gnss_fault_leaves_the_map_fix_out(tmp_path: Path) -> None:
    run = run_scenario(tmp_path, "lane-change",
                       "faults=[{sensor: gnss, kind: nan, start_s: 0.25, end_s: 0.45}]",
                       duration_s=0.6)
    assert run.completed
    counts = {c.topic: c.message_count for c in read_summary(run.log_path).channels}
    assert counts["/gnss/fix"] == counts["/sensors/gnss"] - 2  # 0.3 s and 0.4 s


def _panel_leaves(node: object) -> list[str]:
    if isinstance(node, str):
        return [node]
    assert isinstance(node, dict), node
    assert node["direction"] in ("row", "column")
    assert 0 < node.get("splitPercentage", 50) < 100
    return _panel_leaves(node["first"]) + _panel_leaves(node["second"])


def test_the_layout_is_a_foxglove_layout_of_this_logs_topics(short_run: RunResult) -> None:
    layout = json.loads(LAYOUT.read_text())
    assert {"configById", "layout", "globalVariables", "userNodes",
            "playbackConfig"} <= set(layout)
    panels = layout["configById"]
    leaves = _panel_leaves(layout["layout"])
    assert sorted(leaves) == sorted(panels)  # every panel placed once, none missing
    for panel_id in panels:
        assert re.fullmatch(r"(3D|Map|Plot|RawMessages)![A-Za-z0-9]+", panel_id), panel_id
    first: dict[str, dict] = {}
    for topic, _, message in iter_topics(short_run.log_path):
        first.setdefault(topic, message)

    def check_path(path: str) -> None:
        topic, _, field = path.partition(".")
        assert topic in first, path
        if field:
            assert field.split(".")[0] in first[topic], path

    three_d = panels["3D!car"]
    assert three_d["followTf"] == "base_link"
    assert set(three_d["topics"]) == set(SCENE_TOPICS)
    assert all(t["visible"] for t in three_d["topics"].values())
    for topic in three_d["topics"]:
        check_path(topic)
    check_path(panels["Map!gnss"]["followTopic"])
    check_path(panels["RawMessages!metrics"]["topicPath"])
    plots = [p for panel_id, p in panels.items() if panel_id.startswith("Plot!")]
    assert len(plots) >= 4
    for plot in plots:
        assert plot["paths"]
        for path in plot["paths"]:
            check_path(path["value"])


EPOCH_2026_NS = 1_767_225_600 * 1_000_000_000
"""2026-01-01T00:00:00Z in nanoseconds since 1970 (1767225600 s: 56 years and 14 leap days)."""


def _raw_log_times(path: Path) -> dict[str, list[int]]:
    """Every message's log time as written in the file (no epoch subtracted), per topic."""
    from mcap.reader import make_reader

    times: dict[str, list[int]] = {}
    with open(path, "rb") as stream:
        for _, channel, message in make_reader(stream).iter_messages(log_time_order=False):
            times.setdefault(channel.topic, []).append(message.log_time)
    return times


def test_log_times_are_the_epoch_plus_sim_time(short_run: RunResult) -> None:
    summary = read_summary(short_run.log_path)
    assert summary.metadata["run"]["epoch"] == "2026-01-01T00:00:00Z"
    assert summary.epoch_ns == EPOCH_2026_NS
    raw = _raw_log_times(short_run.log_path)
    assert min(min(times) for times in raw.values()) >= EPOCH_2026_NS
    truth = [m["t_s"] for _, m in iter_messages(short_run.log_path, "/vehicle/truth")]
    assert raw["/vehicle/truth"] == [EPOCH_2026_NS + round(t * 1e9) for t in truth]
    # Readers subtract the epoch: sim time stays sim time.
    sim_ns = [t for t, _ in iter_messages(short_run.log_path, "/vehicle/truth")]
    assert sim_ns == [round(t * 1e9) for t in truth]
    assert sim_ns[0] == 0


def test_the_epoch_is_configurable_and_checked(tmp_path: Path) -> None:
    from cosim.core.exceptions import ConfigError
    from cosim.simulation.scenario_config import load_config

    result = run_scenario(tmp_path, "lane-change", "sim.epoch=2030-06-01T12:00:00+02:00",
                          duration_s=0.1)
    raw = _raw_log_times(result.log_path)
    epoch_ns = (1_906_545_600 - 2 * 3600) * 1_000_000_000  # 2030-06-01T10:00:00Z
    assert min(raw["/vehicle/truth"]) == epoch_ns
    assert read_summary(result.log_path).epoch_ns == epoch_ns
    for bad in ("yesterday", "2026-01-01T00:00:00", "1960-01-01T00:00:00Z"):
        with pytest.raises(ConfigError, match="sim.epoch"):
            load_config("lane-change", overrides=[f"sim.epoch={bad}"])


@pytest.mark.slow
def test_live_metrics_every_second_end_at_the_final_metrics(lane_change_run: RunResult) -> None:
    live = list(iter_messages(lane_change_run.log_path, "/metrics/live"))
    assert len(live) >= 14
    assert [m["t_s"] for _, m in live] == pytest.approx([float(n + 1) for n in range(len(live))])
    cte_max = [m["cte_max_m"] for _, m in live]
    assert cte_max == sorted(cte_max)  # a running maximum never falls
    final = lane_change_run.metrics
    for key in ("cte_max_m", "cte_rms_m", "heading_err_max_rad", "speed_err_rms_mps"):
        assert live[-1][1][key] == pytest.approx(final[key]), key


def test_live_metrics_are_running_values(short_run: RunResult) -> None:
    (live,) = [m for _, m in iter_messages(short_run.log_path, "/metrics/live")][:1]
    errors = [m for _, m in iter_messages(short_run.log_path, "/control/errors")
              if m["t_s"] <= live["t_s"] + 1e-9]
    assert live["cte_max_m"] == pytest.approx(max(abs(m["cte_m"]) for m in errors))
    assert live["cte_rms_m"] == pytest.approx(
        math.sqrt(sum(m["cte_m"] ** 2 for m in errors) / len(errors)))


def test_dynamic_mpc_has_a_plan_scene(tmp_path: Path) -> None:
    result = run_scenario(tmp_path, "lane-change", "tracker.name=dynamic-mpc", duration_s=1.0)
    plans = dict(iter_messages(result.log_path, "/control/plan"))
    scenes = dict(iter_messages(result.log_path, "/scene/plan"))
    assert scenes.keys() == plans.keys() and len(scenes) == 20
    truth = dict(iter_messages(result.log_path, "/vehicle/truth"))
    for t_ns, scene in scenes.items():
        (line,) = scene["entities"][0]["lines"]
        points = np.array([[p["x"], p["y"]] for p in line["points"]])
        predicted = np.column_stack([plans[t_ns]["predicted_x_m"], plans[t_ns]["predicted_y_m"]])
        assert points == pytest.approx(predicted, abs=1e-4)
        # The plan starts where the car is (the estimate, within centimetres of the truth).
        assert points[0] == pytest.approx([truth[t_ns]["x_m"], truth[t_ns]["y_m"]], abs=0.1)
