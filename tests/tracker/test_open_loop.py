"""The open-loop tracker and its manoeuvres (steering profiles, speed hold, metrics)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from cosim.core.exceptions import ConfigError
from cosim.core.records import Estimate
from cosim.simulation.manoeuvre_metrics import manoeuvre_metrics
from cosim.simulation.runner import run
from cosim.simulation.scenario_config import load_config
from tracker.config import TrackerConfig
from tracker.manoeuvre import ManoeuvreConfig
from tracker.open_loop import OpenLoopTracker
from tracker.paths.double_lane_change import double_lane_change


def _estimate(vx_mps: float) -> Estimate:
    names = ("x_m", "y_m", "yaw_rad", "vx_mps")
    return Estimate(0.0, names, np.array([0.0, 0.0, 0.0, vx_mps]), np.eye(4))


def test_step_steer_ramps_at_its_rate_then_holds() -> None:
    manoeuvre = ManoeuvreConfig(kind="step-steer", steer_rad=-0.07, step_time_s=1.0,
                              step_rate_radps=0.7)
    assert manoeuvre.steer_at(0.99) == 0.0
    assert manoeuvre.steer_at(1.05) == pytest.approx(-0.035)
    assert manoeuvre.steer_at(1.1) == pytest.approx(-0.07)
    assert manoeuvre.steer_at(30.0) == pytest.approx(-0.07)


def test_ramp_steer_grows_linearly_to_its_final_angle() -> None:
    manoeuvre = ManoeuvreConfig(kind="ramp-steer", steer_rad=0.2, step_time_s=2.0,
                              ramp_rate_radps=0.01)
    assert manoeuvre.steer_at(2.0) == 0.0
    assert manoeuvre.steer_at(12.0) == pytest.approx(0.1)
    assert manoeuvre.steer_at(100.0) == pytest.approx(0.2)


def test_speed_loop_is_proportional_and_bounded() -> None:
    tracker = OpenLoopTracker(TrackerConfig(name="open-loop"),
                              ManoeuvreConfig(speed_mps=10.0, speed_gain_1ps=0.5, steer_rad=0.1))
    path = double_lane_change(10.0)
    command, plan = tracker.step(0.0, _estimate(9.0), path)
    assert command.accel_mps2 == pytest.approx(0.5)
    assert command.steer_rad == pytest.approx(0.1)
    assert plan.success and not plan.fallback and plan.status == "open-loop"
    command, _ = tracker.step(0.0, _estimate(0.0), path)
    assert command.accel_mps2 == pytest.approx(3.0)  # tracker.accel_max_mps2


def test_steer_is_clipped_to_the_trackers_bound() -> None:
    tracker = OpenLoopTracker(TrackerConfig(name="open-loop"), ManoeuvreConfig(steer_rad=0.9))
    command, _ = tracker.step(0.0, _estimate(10.0), double_lane_change(10.0))
    assert command.steer_rad == pytest.approx(math.pi / 8)


def test_unknown_manoeuvre_kind_names_the_key() -> None:
    with pytest.raises(ConfigError, match="manoeuvre.kind = 'figure-eight'"):
        load_config("steady-circle", overrides=["manoeuvre.kind=figure-eight"])


def test_step_metrics_on_a_known_first_order_response() -> None:
    t = np.arange(0.0, 5.0, 0.01)
    manoeuvre = ManoeuvreConfig(kind="step-steer", steer_rad=0.1, step_time_s=1.0,
                              step_rate_radps=100.0, steady_window_s=1.0)
    steer = np.array([manoeuvre.steer_at(ti) for ti in t])
    tau = 0.2
    yaw_rate = np.where(t > 1.0, 0.5 * (1 - np.exp(-(t - 1.0) / tau)), 0.0)
    metrics = manoeuvre_metrics(t, steer, yaw_rate, 10 * yaw_rate, np.full(t.size, 20.0),
                               manoeuvre)
    # 90 % of a first-order step is reached after tau ln 10.
    assert metrics["yaw_rate_response_time_s"] == pytest.approx(tau * math.log(10), abs=0.015)
    assert metrics["yaw_rate_overshoot"] == pytest.approx(0.0, abs=1e-3)
    assert metrics["steady_yaw_rate_gain_1ps"] == pytest.approx(5.0, rel=1e-3)


@pytest.mark.slow
def test_steady_circle_at_low_speed_follows_the_ackermann_radius(tmp_path: Path) -> None:
    config = load_config("steady-circle", overrides=[
        "manoeuvre.speed_mps=5", "initial.speed_mps=5", "manoeuvre.steer_rad=0.1",
        "sim.duration_s=15"])
    result = run(config, tmp_path / "circle.mcap")
    metrics = result.metrics
    wheelbase_m = config.plant.cog_front_m + config.plant.cog_rear_m
    assert metrics["completed"] is True
    assert metrics["steady_speed_mps"] == pytest.approx(5.0, abs=0.05)
    assert metrics["steady_radius_m"] == pytest.approx(wheelbase_m / math.tan(0.1), rel=0.05)
