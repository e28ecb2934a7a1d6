"""Closed-loop checks of the kinematic NMPC on its own model.

The car is the plain-numpy kinematic bicycle of :mod:`tests.tracker.closed_loop` at 2 ms,
the controller runs every 50 ms on a perfect estimate. On its own model the NMPC must do
better than the 88 mm bar of a delta-u MPC (see tracker.dynamic_mpc) on the stretched double lane
change.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from cosim.core.config_fields import from_dict
from cosim.core.records import Command, Estimate
from tests.tracker.closed_loop import (
    ESTIMATE_NAMES,
    CarState,
    ClosedLoopResult,
    estimate_of,
    run_closed_loop,
)
from tests.tracker.contract import (
    assert_commands_within_bounds,
    assert_every_solve_succeeded,
    assert_reaches_speed,
    assert_tracks_the_lane_change,
)
from tracker.config import TrackerConfig
from tracker.mpc.kinematic_nmpc import KinematicNmpc
from tracker.paths.double_lane_change import double_lane_change
from tracker.paths.reference_path import ReferencePath

CONFIG = from_dict(TrackerConfig, {"name": "kinematic-nmpc", "latency_s": 0.0,
                                   "kinematic_understeer": False,
                                   "model": {"steer_time_constant_s": 0.0}})
"""The default tuning on the kinematic model, the bench's own; the bench acts
instantly (no transport delay, no steering lag), so there is no latency to predict over."""
LANE_CHANGE = double_lane_change(20.0, 1.5)


@pytest.fixture(scope="module")
def lane_change() -> ClosedLoopResult:
    """The stretched double lane change at 20 m/s from 15 m/s, 15 s (Falcone et al. 2007, stretched
    by 1.5)."""
    tracker = KinematicNmpc(CONFIG)
    return run_closed_loop(tracker, LANE_CHANGE, CarState(0.0, 0.0, 0.0, 15.0), 15.0,
                           CONFIG.model)


def test_lane_change_is_tracked_within_centimetres(lane_change: ClosedLoopResult) -> None:
    assert_tracks_the_lane_change(lane_change.cte_m, lane_change.final.x_m, 0.06)


def test_lane_change_reaches_reference_speed(lane_change: ClosedLoopResult) -> None:
    assert_reaches_speed(lane_change.speed_mps, 20.0, within_s=4.0)


def test_lane_change_has_no_solver_failures(lane_change: ClosedLoopResult) -> None:
    assert_every_solve_succeeded(lane_change.plans, CONFIG)


def test_lane_change_commands_within_bounds(lane_change: ClosedLoopResult) -> None:
    assert_commands_within_bounds(lane_change.commands, CONFIG)


def test_lane_change_plan_is_complete(lane_change: ClosedLoopResult) -> None:
    plan = lane_change.plans[100]
    n = CONFIG.horizon
    assert plan.state_names == ("x_m", "y_m", "yaw_rad", "vx_mps")
    assert plan.input_names == ("accel_mps2", "steer_rad")
    assert plan.states.shape == (n + 1, 4)
    assert plan.inputs.shape == (n, 2)
    assert plan.dt_s == CONFIG.dt_s
    assert plan.t_s == pytest.approx(100 * 0.05)
    assert plan.solve_time_s > 0.0
    assert plan.status == "Solve_Succeeded"
    command = lane_change.commands[100]
    assert command.t_s == plan.t_s
    assert command.steer_rad == plan.column("steer_rad")[0]
    assert command.accel_mps2 == plan.column("accel_mps2")[0]
    # Without latency the plan starts at the estimate.
    estimate = lane_change.estimates[100]
    assert plan.states[0] == pytest.approx([estimate[n] for n in plan.state_names], abs=1e-6)
    message = plan.to_message()
    assert len(message["predicted_x_m"]) == n + 1


def test_recovers_from_a_lateral_offset() -> None:
    tracker = KinematicNmpc(CONFIG)
    straight = ReferencePath(np.linspace(0.0, 400.0, 401), np.zeros(401), 20.0)
    result = run_closed_loop(tracker, straight, CarState(0.0, 1.0, 0.0, 20.0), 6.0,
                             CONFIG.model)
    assert result.cte_m[0] == pytest.approx(1.0, abs=0.01)
    t = np.arange(result.cte_m.size) * 0.002
    # Within 10 % of the offset after 1.5 s, settled after 3 s, overshoot under 10 %.
    assert np.max(np.abs(result.cte_m[t > 1.5])) < 0.1
    assert np.max(np.abs(result.cte_m[t > 3.0])) < 0.02
    assert np.min(result.cte_m) > -0.1
    assert not any(plan.fallback for plan in result.plans)


def test_heading_across_the_angle_wrap() -> None:
    # Driving west (path yaw pi) and weaving across yaw = +-pi: the estimate's yaw jumps
    # by 2 pi, the controller must not.
    x = np.linspace(0.0, -400.0, 401)
    west = ReferencePath(x, np.zeros_like(x), 15.0)
    tracker = KinematicNmpc(CONFIG)
    start = CarState(0.0, 0.5, math.pi - 0.05, 15.0)
    result = run_closed_loop(tracker, west, start, 5.0, CONFIG.model)
    yaws = [e["yaw_rad"] for e in result.estimates]
    assert min(yaws) < -3.0 and max(yaws) > 3.0  # the estimate did cross the wrap
    steer = np.array([c.steer_rad for c in result.commands])
    assert np.max(np.abs(steer)) < 0.1
    assert np.max(np.abs(result.cte_m[-500:])) < 0.02
    assert not any(plan.fallback for plan in result.plans)


def test_forced_solver_failure_falls_back_then_stops_safely() -> None:
    # IPOPT at one iteration: every solve fails, named Maximum_Iterations_Exceeded.
    config = from_dict(TrackerConfig, {"name": "kinematic-nmpc", "max_iterations": 1,
                                       "solver": "ipopt", "kinematic_understeer": False})
    tracker = KinematicNmpc(config)
    tracker.reset(Command(t_s=0.0, accel_mps2=0.0, steer_rad=0.05))
    state = CarState(0.0, 0.5, 0.0, 15.0)
    plans, commands = [], []
    for i in range(20):
        t_s = i * 0.05
        command, plan = tracker.step(t_s, estimate_of(t_s, state), LANE_CHANGE)
        plans.append(plan)
        commands.append(command)
    assert all(plan.fallback and not plan.success for plan in plans)
    assert all("Maximum_Iterations_Exceeded" in plan.status for plan in plans)
    assert all(math.isnan(plan.cost) for plan in plans)
    # Within fallback_time_s the last applied actuation (no good plan yet) is held.
    replaying = [t_s <= config.fallback_time_s + 1e-9 for t_s in (p.t_s for p in plans)]
    held = [(c, p) for c, p, r in zip(commands, plans, replaying, strict=True) if r]
    assert len(held) == 11  # t = 0 .. 0.5 s
    assert all(p.status.startswith("fallback") for _, p in held)
    assert all(c.steer_rad == 0.05 and c.accel_mps2 == 0.0 for c, _ in held)
    # Then a safe stop: braking, steering back to zero at the rate limit, then held.
    stopping = [(c, p) for c, p, r in zip(commands, plans, replaying, strict=True) if not r]
    assert stopping and all(p.status.startswith("safe_stop") for _, p in stopping)
    assert all(c.accel_mps2 == config.safe_stop_accel_mps2 for c, _ in stopping)
    steer_steps = np.diff([0.05] + [c.steer_rad for c, _ in stopping])
    assert np.all(steer_steps <= 0.0)
    assert np.all(steer_steps >= -config.max_steer_rate_radps * 0.05 - 1e-12)
    assert stopping[-1][0].steer_rad == 0.0
    # The plan of a safe stop ends at standstill and never reverses.
    speeds = stopping[-1][1].column("vx_mps")
    assert np.all(speeds >= -1e-9)


def test_fallback_replays_the_last_good_plan() -> None:
    tracker = KinematicNmpc(CONFIG)
    state = CarState(0.0, 0.0, 0.0, 15.0)
    _, good = tracker.step(0.0, estimate_of(0.0, state), LANE_CHANGE)
    assert good.success
    nan_estimate = Estimate(0.05, ESTIMATE_NAMES, np.full(4, np.nan), np.eye(4))
    command, plan = tracker.step(0.05, nan_estimate, LANE_CHANGE)
    assert plan.fallback and not plan.success
    assert "non_finite_estimate" in plan.status
    # Shifted by one stage: the second input of the good plan.
    assert command.steer_rad == pytest.approx(good.column("steer_rad")[1])
    assert command.accel_mps2 == pytest.approx(good.column("accel_mps2")[1])
    # The next good estimate is solved normally again.
    _, again = tracker.step(0.10, estimate_of(0.10, state), LANE_CHANGE)
    assert again.success and not again.fallback


def test_same_inputs_give_identical_commands() -> None:
    first = KinematicNmpc(CONFIG)
    result = run_closed_loop(first, LANE_CHANGE, CarState(0.0, 0.3, 0.02, 15.0), 3.0,
                             CONFIG.model)
    second = KinematicNmpc(CONFIG)
    replayed = [second.step(e.t_s, e, LANE_CHANGE)[0] for e in result.estimates]
    assert replayed == result.commands
    first.reset()
    again = [first.step(e.t_s, e, LANE_CHANGE)[0] for e in result.estimates]
    assert again == result.commands


def test_wrong_name_is_refused() -> None:
    from cosim.core.exceptions import ConfigError

    with pytest.raises(ConfigError, match="kinematic-nmpc"):
        KinematicNmpc(dataclasses.replace(CONFIG, name="pure-pursuit"))
