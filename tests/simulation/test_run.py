"""Closed-loop runs: determinism, the MCAP contract, and the lane change itself."""

from __future__ import annotations

import json
import math
from pathlib import Path

import jsonschema
import numpy as np
import pytest
from mcap.reader import make_reader

from cosim.log.reader import iter_messages, read_summary
from cosim.simulation.metrics import METRIC_KEYS, WALL_CLOCK_KEYS
from cosim.simulation.runner import RunResult, run_unlogged
from cosim.simulation.scenario_config import load_config
from tests.conftest import run_scenario

DESIGN_TOPICS = {
    "/vehicle/truth", "/vehicle/estimate", "/control/command", "/control/plan",
    "/reference/path", "/metrics", "/tf", "/scene", "/sensors/gnss", "/sensors/imu",
    "/sensors/wheel_speed",
}


def _payloads(path: Path) -> dict[str, list[bytes]]:
    """Every message's raw bytes by topic, read with the mcap package's own reader."""
    payloads: dict[str, list[bytes]] = {}
    with open(path, "rb") as stream:
        for _, channel, message in make_reader(stream).iter_messages(log_time_order=False):
            payloads.setdefault(channel.topic, []).append(message.data)
    return payloads


def _strip_wall_clock(payloads: dict[str, list[bytes]]) -> dict[str, list[object]]:
    stripped: dict[str, list[object]] = {}
    for topic, messages in payloads.items():
        decoded: list[object] = []
        for data in messages:
            message = json.loads(data)
            for key in {*WALL_CLOCK_KEYS, "solve_time_s"}:
                message.pop(key, None)
            decoded.append(message)
        stripped[topic] = decoded
    return stripped


def test_one_seed_gives_one_result(short_run: RunResult, tmp_path: Path) -> None:
    again = run_scenario(tmp_path, "lane-change", duration_s=2.0)
    first, second = _payloads(short_run.log_path), _payloads(again.log_path)
    assert set(first) == set(second)
    # Simulation payloads are bit-identical: truth, sensors, estimates, commands.
    for topic in ("/vehicle/truth", "/vehicle/estimate", "/control/command",
                  "/sensors/gnss", "/sensors/imu", "/sensors/wheel_speed", "/tf"):
        assert first[topic] == second[topic], topic
    # Plans and metrics differ only in wall-clock timing fields.
    assert _strip_wall_clock(first) == _strip_wall_clock(second)


def test_a_run_without_a_log_has_the_logged_runs_metrics_bit_for_bit(
        short_run: RunResult) -> None:
    # What a sweep that keeps no logs runs: no message is built, and nothing it simulates,
    # estimates or measures changes (logging observes the loop).
    unlogged = run_unlogged(load_config("lane-change", duration_s=2.0))
    assert unlogged.log_path is None and unlogged.completed
    compared = {k for k in short_run.metrics if k not in WALL_CLOCK_KEYS and "_ms_" not in k}
    assert len(compared) > 40
    for key in sorted(compared):
        logged, other = short_run.metrics[key], unlogged.metrics[key]
        assert logged == other or (logged != logged and other != other), key


def test_another_seed_gives_other_noise(short_run: RunResult, tmp_path: Path) -> None:
    other = run_scenario(tmp_path, "lane-change", duration_s=2.0, seed=1)
    first, second = _payloads(short_run.log_path), _payloads(other.log_path)
    assert first["/sensors/gnss"] != second["/sensors/gnss"]
    assert first["/vehicle/truth"] != second["/vehicle/truth"]


def test_log_has_every_design_topic_with_a_schema(short_run: RunResult) -> None:
    summary = read_summary(short_run.log_path)
    topics = {c.topic: c for c in summary.channels}
    assert DESIGN_TOPICS <= set(topics)
    for channel in summary.channels:
        assert channel.schema_name, channel.topic
        assert channel.schema_encoding == "jsonschema"
        assert channel.message_count > 0, channel.topic
    assert topics["/tf"].schema_name == "foxglove.FrameTransform"
    assert topics["/scene"].schema_name == "foxglove.SceneUpdate"
    assert topics["/metrics"].message_count == 1
    # 2 s at the default rates: truth at 100 Hz, GNSS at 10 Hz, control at 20 Hz.
    assert topics["/vehicle/truth"].message_count == 201
    assert topics["/sensors/gnss"].message_count == 21
    assert topics["/control/plan"].message_count == 40
    assert not summary.truncated
    assert summary.duration_s == pytest.approx(2.0)


def test_metadata_attachment_and_metrics_round_trip(short_run: RunResult) -> None:
    summary = read_summary(short_run.log_path)
    assert summary.config["name"] == "lane-change"
    assert summary.config["seed"] == 0
    assert {"cosim", "mujoco", "casadi", "filterpy"} <= set(summary.versions)
    assert "sedan.xml" in summary.attachments
    assert summary.metrics is not None
    assert set(METRIC_KEYS) <= set(summary.metrics)
    assert summary.metrics["cte_max_m"] == pytest.approx(short_run.metrics["cte_max_m"])
    assert summary.metrics["completed"] is True
    # The /metrics message is the last message in the file.
    with open(short_run.log_path, "rb") as stream:
        messages = list(make_reader(stream).iter_messages(log_time_order=False))
    assert messages[-1][1].topic == "/metrics"


def test_truth_messages_carry_the_vehicle_state_fields(short_run: RunResult) -> None:
    _, first = next(iter_messages(short_run.log_path, "/vehicle/truth"))
    for name in ("t_s", "x_m", "y_m", "yaw_rad", "vx_mps", "vy_mps", "yaw_rate_radps",
                 "ax_mps2", "ay_mps2", "steer_rad", "wheel_speed_radps"):
        assert name in first
    assert first["vx_mps"] == pytest.approx(15.0, abs=0.2)
    assert len(first["wheel_speed_radps"]) == 4
    _, estimate = next(iter_messages(short_run.log_path, "/vehicle/estimate"))
    n = len(estimate["state_names"])
    assert len(estimate["covariance"]) == n * n


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2, 3, 4])
def test_lane_change_bar_holds_from_a_sampled_initial_estimate(seed: int,
                                                               tmp_path: Path) -> None:
    """The filter starts from a draw around the truth (``estimator.initial: sampled``, the
    default), not from the truth; the 88 mm bar still holds on seeds 1-4 as on seed 0."""
    metrics = run_scenario(tmp_path, "lane-change", seed=seed, logged=False).metrics
    assert metrics["completed"] is True
    assert metrics["cte_max_m"] <= 0.088


@pytest.mark.slow
def test_lane_change_is_tracked_with_the_ekf_in_the_loop(lane_change_run: RunResult) -> None:
    """Issue 5's bar, a delta-u MPC's on its own model without noise (tracker.dynamic_mpc): max
    lateral deviation 88 mm, heading error under 3 deg, 20 m/s by 5.8 s, steering within
    15 deg and acceleration within 3 m/s^2."""
    metrics = lane_change_run.metrics
    assert metrics["completed"] is True
    assert metrics["sim_duration_s"] == pytest.approx(15.0)
    assert metrics["cte_max_m"] <= 0.088
    assert metrics["heading_err_max_rad"] < math.radians(3.0)
    assert metrics["steer_max_rad"] <= math.radians(15.0)
    assert -3.0 <= metrics["accel_min_mps2"] and metrics["accel_max_mps2"] <= 3.0
    truth = [m for _, m in iter_messages(lane_change_run.log_path, "/vehicle/truth")]
    assert max(m["vx_mps"] for m in truth if m["t_s"] <= 5.8) >= 20.0
    assert metrics["solver_failures"] == 0
    # The estimate fed to the MPC is the filter's, not the truth: it has an error.
    assert 0.0 < metrics["est_pos_rmse_m"] < 0.05
    # The car reaches the reference speed: the last seconds are near 20 m/s.
    speeds = [m["vx_mps"] for _, m in iter_messages(lane_change_run.log_path,
                                                     "/vehicle/truth")][-200:]
    assert min(speeds) > 19.0


@pytest.mark.slow
def test_every_message_matches_its_channel_schema(short_run: RunResult) -> None:
    with open(short_run.log_path, "rb") as stream:
        reader = make_reader(stream)
        checked: dict[str, int] = {}
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            if checked.get(channel.topic, 0) >= 20:
                continue
            jsonschema.validate(json.loads(message.data), json.loads(schema.data))
            checked[channel.topic] = checked.get(channel.topic, 0) + 1
    assert DESIGN_TOPICS <= set(checked)


def test_the_logged_versions_are_the_installed_ones() -> None:
    """The log's versions are read from each package's metadata header: the same strings
    importlib.metadata gives (a release candidate's, a local build's suffix included)."""
    import importlib.metadata

    from cosim.simulation.run_log import versions

    found = versions()
    assert found["cosim"] and len(found) == 8
    for package, version in found.items():
        if package != "cosim":
            assert version == importlib.metadata.version(package), package


def test_the_solve_time_percentiles_are_numpys_to_the_bit() -> None:
    """The metrics' percentiles (written out, without numpy's machinery) give
    ``np.percentile``'s default (linear) values exactly, ties, one value, infinities and NaN
    included."""
    from cosim.simulation.metrics import percentiles

    rng = np.random.default_rng(11)
    cases = [rng.random(n) * 10.0 ** rng.integers(-3, 4) for n in (1, 2, 3, 7, 100, 301)]
    cases += [np.round(rng.random(50), 1), np.array([1.0, np.inf, 2.0]),
              np.array([3.0, np.nan, 1.0]), np.full(9, 0.25)]
    percents = (0.0, 1.0, 37.5, 50.0, 99.0, 100.0)
    for values in cases:
        with np.errstate(invalid="ignore"):  # numpy's own lerp over an infinity
            expected = np.percentile(values, percents)
        assert np.array_equal(percentiles(values, percents), expected, equal_nan=True), values
