"""Latency and disturbances on the MuJoCo car: actuator delay with and without latency
compensation, and the unmeasured heading step, with the EKF in the loop."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from cosim.log.reader import iter_messages
from cosim.plant.disturbances import DisturbanceConfig, schedule
from cosim.simulation.runner import RunResult, component_rng
from cosim.simulation.scenario_config import load_config
from tests.conftest import run_scenario
from tracker.paths.reference_path import ReferencePath


def test_the_tracker_is_told_the_plant_delay_only_when_asked() -> None:
    """No belief follows the plant silently: the delay is the plant's side alone unless
    the belief says ``plant`` (then it takes the plant's resolved value, recorded)."""
    delayed = load_config("lane-change", overrides=["plant.actuator_delay_s=0.1"])
    assert delayed.tracker.latency_s == 0.0 and delayed.beliefs_from_plant == {}
    told = load_config("lane-change", overrides=["plant.actuator_delay_s=0.1",
                                                 "tracker.latency_s=plant"])
    assert told.tracker.latency_s == pytest.approx(0.1)
    assert told.beliefs_from_plant == {"tracker.latency_s": "plant.actuator_delay_s"}
    wrong = load_config("lane-change", overrides=["plant.actuator_delay_s=0.1",
                                                  "tracker.latency_s=0.05"])
    assert wrong.tracker.latency_s == pytest.approx(0.05)
    assert load_config("lane-change").tracker.latency_s == 0.0


@pytest.mark.slow
def test_latency_compensation_keeps_a_100ms_delay_harmless(
    lane_change_run: RunResult, tmp_path: Path
) -> None:
    """A 100 ms delay the tracker is told: with compensation it adds at most 25 mm to the
    no-delay max CTE (seed 0: 29.1 -> 50.6 mm, measured 2026-12-06); without, the max CTE
    is more than twice as large. (Until 2026-12-06 the bar was 1.5x the no-delay max CTE,
    then 50.0 -> 68.5 mm with the slower wheel of then; the faster wheel is closer with
    the delay and without, and the delay's share is larger.)"""
    nominal = lane_change_run.metrics["cte_max_m"]
    compensated = run_scenario(tmp_path, "lane-change", "plant.actuator_delay_s=0.1",
                               "tracker.latency_s=plant")
    uncompensated = run_scenario(tmp_path, "lane-change", "plant.actuator_delay_s=0.1",
                                 "tracker.latency_s=plant",
                                 "tracker.latency_compensation=false", seed=0)
    assert compensated.metrics["completed"] is True
    assert compensated.metrics["solver_failures"] == 0
    assert compensated.metrics["cte_max_m"] <= nominal + 0.025
    assert uncompensated.metrics["cte_max_m"] > 2.0 * compensated.metrics["cte_max_m"]


def _cte_after(result: RunResult, t_from_s: float) -> np.ndarray:
    path_message = next(m for _, m in iter_messages(result.log_path, "/reference/path"))
    path = ReferencePath(np.array(path_message["x_m"]), np.array(path_message["y_m"]),
                         path_message["speed_mps"])
    return np.array([
        path.project(m["x_m"], m["y_m"]).lateral_error_m
        for _, m in iter_messages(result.log_path, "/vehicle/truth") if m["t_s"] >= t_from_s
    ])


@pytest.mark.slow
def test_an_unmeasured_5_deg_heading_step_is_rejected(tmp_path: Path) -> None:
    """The unmeasured heading-step disturbance on the straight after the lane change (9 s): the car
    is kicked 5 deg to the left and steered back; the errors return to zero. The gyro sees the
    kick far outside its gate, and the filter makes room for it in the yaw rate
    (``estimator.inflate_on_surprise``; without it the kick went into the gyro bias, the yaw
    estimate stayed 0.03 rad behind, the GNSS gate refused the fixes and the car left the road
    by 2.1 m)."""
    result = run_scenario(tmp_path, "lane-change",
                          "disturbances=[{t_s: 9.0, random: false, angle_rad: 0.087}]")
    metrics = result.metrics
    assert metrics["completed"] is True and metrics["solver_failures"] == 0
    kicks = [m for _, m in iter_messages(result.log_path, "/plant/disturbance")]
    assert [k["t_s"] for k in kicks] == pytest.approx([9.0, 9.1])
    assert kicks[0]["heading_step_rad"] == pytest.approx(0.087)
    after = _cte_after(result, 9.0)
    assert np.max(np.abs(after)) > 0.02  # the kick did move the car off the path ...
    assert metrics["cte_max_m"] < 0.3  # ... not far ...
    assert np.max(np.abs(after[-100:])) < 0.02  # ... and it is back on it 5 s later
    assert metrics["estimator_surprises"] >= 2  # the kick's start and end, at least


def test_heading_steps_are_drawn_per_seed_within_their_bound() -> None:
    entries = (DisturbanceConfig(t_s=1.0), DisturbanceConfig(t_s=0.5, duration_s=0.05))
    first = schedule(entries, 0.002, component_rng(3, "disturbances"))
    again = schedule(entries, 0.002, component_rng(3, "disturbances"))
    other = schedule(entries, 0.002, component_rng(4, "disturbances"))
    assert first == again and first != other
    assert [c.step for c in first] == [250, 275, 500, 550]
    for change in first:
        assert abs(change.angle_rad) <= math.radians(5.0)
    # Each step is a pulse: the rate changes cancel, their integral is the angle.
    by_angle: dict[float, list[float]] = {}
    for change in first:
        by_angle.setdefault(change.angle_rad, []).append(change.delta_radps)
    for rates in by_angle.values():
        assert rates[0] == -rates[1]
    assert first[0].delta_radps * 0.05 == pytest.approx(first[0].angle_rad)


def test_a_fixed_step_larger_than_its_bound_is_refused() -> None:
    from cosim.core.exceptions import ConfigError

    with pytest.raises(ConfigError, match="angle_rad = 0.2"):
        DisturbanceConfig(random=False, angle_rad=0.2, max_rad=0.1)
