"""Closed-loop checks of the dynamic NMPC on its own model.

The car is the plain-numpy linear-tyre dynamic bicycle of
:mod:`tests.tracker.dynamic_closed_loop` at 2 ms with the plant's steering actuator (50 ms
lag, 0.8 rad/s); the controller runs every 50 ms on a perfect estimate (which, like the
EKF's, carries no steering angle). On its own model the NMPC must do far better than the
88 mm bar of a delta-u MPC (see tracker.dynamic_mpc) on the stretched double lane change.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from cosim.core.config_fields import from_dict
from cosim.core.exceptions import ConfigError
from cosim.core.records import Command, Estimate
from tests.tracker.contract import (
    assert_commands_within_bounds,
    assert_every_solve_succeeded,
    assert_reaches_speed,
    assert_tracks_the_lane_change,
)
from tests.tracker.dynamic_closed_loop import (
    ESTIMATE_NAMES,
    Car,
    ClosedLoopResult,
    estimate_of,
    run_closed_loop,
)
from tracker.config import TrackerConfig
from tracker.models.dynamic_bicycle import DynamicBicycleParams
from tracker.models.steered_dynamic_bicycle import (
    STATE_NAMES,
    SteeredBicycleParams,
    linear_range_slip_rad,
    slip_angle_function,
)
from tracker.models.tyre_limits import friction_usage_function
from tracker.mpc.dynamic_nmpc import DynamicNmpc
from tracker.mpc.grip_config import GripConfig
from tracker.paths.double_lane_change import double_lane_change
from tracker.paths.reference_path import ReferencePath

CONFIG = from_dict(TrackerConfig, {"name": "dynamic-nmpc"})
"""The default tuning and belief; the bench has no transport delay (``latency_s = 0``)."""
BELIEF = SteeredBicycleParams.from_vehicle(CONFIG.model)
CAR = DynamicBicycleParams.from_vehicle(CONFIG.model, CONFIG.model.cornering_stiffness_front_npr,
                                        CONFIG.model.cornering_stiffness_rear_npr)
"""The bench car is the belief: the controller's own model."""
LANE_CHANGE = double_lane_change(20.0, 1.5)
PERIOD_STEPS = 25
"""Physics steps (2 ms) per control period (50 ms)."""


@pytest.fixture(scope="module")
def lane_change() -> ClosedLoopResult:
    """The stretched double lane change at 20 m/s from 15 m/s, 15 s (Falcone et al. 2007, stretched
    by 1.5)."""
    return run_closed_loop(DynamicNmpc(CONFIG), LANE_CHANGE, Car(0.0, 0.0, 0.0, 15.0), 15.0, CAR)


def test_lane_change_is_tracked_within_centimetres(lane_change: ClosedLoopResult) -> None:
    assert_tracks_the_lane_change(lane_change.cte_m, lane_change.final.x_m, 0.06)


def test_lane_change_reaches_reference_speed(lane_change: ClosedLoopResult) -> None:
    assert_reaches_speed(lane_change.vx_mps, 20.0, within_s=4.0)


def test_lane_change_has_no_solver_failures(lane_change: ClosedLoopResult) -> None:
    assert_every_solve_succeeded(lane_change.plans, CONFIG)


def test_lane_change_commands_within_bounds(lane_change: ClosedLoopResult) -> None:
    assert_commands_within_bounds(lane_change.commands, CONFIG)


def test_lane_change_keeps_the_tyres_in_their_linear_range(
        lane_change: ClosedLoopResult) -> None:
    # At 0.5 g the soft slip limits never bind: every planned slip angle is inside them.
    slip = slip_angle_function(BELIEF)
    bounds = np.array(linear_range_slip_rad(BELIEF, CONFIG.model.tyre_friction))
    for plan in lane_change.plans:
        for state in plan.states[1:]:
            assert np.all(np.abs(np.asarray(slip(state)).ravel()) < bounds)


def test_lane_change_plan_is_complete(lane_change: ClosedLoopResult) -> None:
    plan = lane_change.plans[100]
    n = CONFIG.horizon
    assert plan.state_names == STATE_NAMES
    assert plan.input_names == ("accel_mps2", "steer_rad")
    assert plan.states.shape == (n + 1, len(STATE_NAMES))
    assert plan.inputs.shape == (n, 2)
    assert plan.t_s == pytest.approx(100 * 0.05)
    assert plan.status == "Solve_Succeeded"
    command = lane_change.commands[100]
    assert command.steer_rad == plan.column("steer_rad")[0]
    assert command.accel_mps2 == plan.column("accel_mps2")[0]
    # Without latency the plan starts at the estimate ...
    estimate = lane_change.estimates[100]
    start = [plan.column(name)[0] for name in ESTIMATE_NAMES]
    assert start == pytest.approx([estimate[name] for name in ESTIMATE_NAMES], abs=1e-9)
    assert len(plan.to_message()["predicted_road_wheel_angle_rad"]) == n + 1


def test_internal_steering_angle_follows_the_actuator(lane_change: ClosedLoopResult) -> None:
    # No estimate carries the road-wheel angle: the tracker propagates it through the
    # actuator lag with the commands it applied. The bench's rate limit never binds here,
    # so node 0 of every plan is the bench's angle at that instant.
    node0 = np.array([plan.column("road_wheel_angle_rad")[0] for plan in lane_change.plans])
    bench = np.concatenate(([0.0], lane_change.steer_rad[PERIOD_STEPS - 1 :: PERIOD_STEPS]))
    assert node0 == pytest.approx(bench[: node0.size], abs=1e-9)


def test_recovers_from_a_lateral_offset() -> None:
    straight = ReferencePath(np.linspace(0.0, 400.0, 401), np.zeros(401), 20.0)
    result = run_closed_loop(DynamicNmpc(CONFIG), straight, Car(0.0, 1.0, 0.0, 20.0), 6.0, CAR)
    t = np.arange(result.cte_m.size) * 0.002
    assert np.max(np.abs(result.cte_m[t > 1.5])) < 0.1
    assert np.max(np.abs(result.cte_m[t > 3.0])) < 0.01
    assert np.min(result.cte_m) > -0.15
    assert not any(plan.fallback for plan in result.plans)


def test_low_speed_is_well_behaved() -> None:
    # From 1 m/s with a 0.5 m offset up to 6 m/s: through the slip-angle guard and the
    # kinematic blend, no failure, no NaN, on the path.
    slow = ReferencePath(np.linspace(0.0, 200.0, 401), np.zeros(401), 6.0)
    result = run_closed_loop(DynamicNmpc(CONFIG), slow, Car(0.0, 0.5, 0.0, 1.0), 8.0, CAR)
    t = np.arange(result.cte_m.size) * 0.002
    assert not any(plan.fallback for plan in result.plans)
    assert all(np.all(np.isfinite(plan.states)) for plan in result.plans)
    assert np.max(np.abs(result.cte_m[t > 4.0])) < 0.01
    assert result.final.vx_mps == pytest.approx(6.0, abs=0.01)


def test_slip_limits_hold_on_the_limit_lane_change() -> None:
    # Falcone's unstretched path at 20 m/s asks for 1.11 g: the plans stay (softly) within
    # the linear range of the tyres (about 12 % over it without the limits). The friction
    # awareness (tracker.grip) is off here: it would slow the car so that the slip limits
    # no longer bind (next test).
    config = dataclasses.replace(CONFIG, grip=GripConfig(tyre_limits=False,
                                                         speed_planning=False))
    slip = slip_angle_function(BELIEF)
    bounds = np.array(linear_range_slip_rad(BELIEF, CONFIG.model.tyre_friction))
    result = run_closed_loop(DynamicNmpc(config), double_lane_change(20.0, 1.0),
                             Car(0.0, 0.0, 0.0, 15.0), 6.0, CAR)
    ratio = max(np.max(np.abs(np.asarray(slip(state)).ravel()) / bounds)
                for plan in result.plans for state in plan.states[1:])
    assert 0.9 < ratio < 1.05
    assert not any(plan.fallback for plan in result.plans)


@pytest.mark.slow
def test_friction_awareness_slows_down_for_the_limit_lane_change() -> None:
    # The same 1.11 g path with tracker.grip on, the tyre limits at any friction (by
    # default only below 0.9): the bends cannot be taken at 20 m/s within 0.85 g, so the
    # plans lower the speed (speed_reduced) and each axle's planned friction usage stays
    # (softly) within usage_max.
    config = dataclasses.replace(CONFIG, grip=GripConfig(tyre_limits_below_friction=2.5))
    usage = friction_usage_function(CONFIG.model, BELIEF, CONFIG.model.tyre_friction)
    result = run_closed_loop(DynamicNmpc(config), double_lane_change(20.0, 1.0),
                             Car(0.0, 0.0, 0.0, 15.0), 6.0, CAR)
    worst = max(float(np.max(np.asarray(usage(state, inputs)).ravel()))
                for plan in result.plans
                for state, inputs in zip(plan.states[:-1], plan.inputs, strict=True))
    assert worst < 1.05 * CONFIG.grip.usage_max**2
    assert any(plan.speed_reduced for plan in result.plans)
    # Up to 20 m/s by 2 s, then slower through the bends (without grip: >= 19.95 m/s).
    t = np.arange(result.vx_mps.size) * 0.002
    assert np.min(result.vx_mps[t > 2.0]) < 19.5
    assert not any(plan.fallback for plan in result.plans)


def test_forced_solver_failure_falls_back_then_stops_safely() -> None:
    # IPOPT at one iteration: every solve fails, named Maximum_Iterations_Exceeded.
    config = dataclasses.replace(CONFIG, max_iterations=1, solver="ipopt")
    tracker = DynamicNmpc(config)
    tracker.reset(Command(t_s=0.0, accel_mps2=0.0, steer_rad=0.05))
    car = Car(0.0, 0.5, 0.0, 15.0)
    plans, commands = [], []
    for i in range(20):
        t_s = i * 0.05
        command, plan = tracker.step(t_s, estimate_of(t_s, car), LANE_CHANGE)
        plans.append(plan)
        commands.append(command)
    assert all(plan.fallback and not plan.success for plan in plans)
    assert all("Maximum_Iterations_Exceeded" in plan.status for plan in plans)
    assert all(math.isnan(plan.cost) for plan in plans)
    replaying = [p.t_s <= config.fallback_time_s + 1e-9 for p in plans]
    held = [(c, p) for c, p, r in zip(commands, plans, replaying, strict=True) if r]
    assert len(held) == 11  # t = 0 .. 0.5 s
    assert all(p.status.startswith("fallback") for _, p in held)
    assert all(c.steer_rad == 0.05 and c.accel_mps2 == 0.0 for c, _ in held)
    # reset() put the actuator at rest at the applied command.
    assert held[0][1].column("road_wheel_angle_rad")[0] == pytest.approx(0.05)
    stopping = [(c, p) for c, p, r in zip(commands, plans, replaying, strict=True) if not r]
    assert stopping and all(p.status.startswith("safe_stop") for _, p in stopping)
    assert all(c.accel_mps2 == config.safe_stop_accel_mps2 for c, _ in stopping)
    steer_steps = np.diff([0.05] + [c.steer_rad for c, _ in stopping])
    assert np.all(steer_steps <= 0.0)
    assert np.all(steer_steps >= -config.max_steer_rate_radps * 0.05 - 1e-12)
    assert stopping[-1][0].steer_rad == 0.0
    speeds = stopping[-1][1].column("vx_mps")
    assert np.all(speeds >= -1e-9)
    assert np.all(np.isfinite(stopping[-1][1].states))


def test_fallback_replays_the_last_good_plan() -> None:
    tracker = DynamicNmpc(CONFIG)
    car = Car(0.0, 0.0, 0.0, 15.0)
    _, good = tracker.step(0.0, estimate_of(0.0, car), LANE_CHANGE)
    assert good.success
    names = ESTIMATE_NAMES
    nan_estimate = Estimate(0.05, names, np.full(len(names), np.nan), np.eye(len(names)))
    command, plan = tracker.step(0.05, nan_estimate, LANE_CHANGE)
    assert plan.fallback and not plan.success
    assert "non_finite_estimate" in plan.status
    assert command.steer_rad == pytest.approx(good.column("steer_rad")[1])
    assert command.accel_mps2 == pytest.approx(good.column("accel_mps2")[1])
    _, again = tracker.step(0.10, estimate_of(0.10, car), LANE_CHANGE)
    assert again.success and not again.fallback
    # The actuator state survived the bad estimate: still finite, from the applied commands.
    assert math.isfinite(again.column("road_wheel_angle_rad")[0])


@pytest.mark.slow
def test_same_inputs_give_identical_commands() -> None:
    first = DynamicNmpc(CONFIG)
    result = run_closed_loop(first, LANE_CHANGE, Car(0.0, 0.3, 0.02, 15.0), 3.0, CAR)
    second = DynamicNmpc(CONFIG)
    replayed = [second.step(e.t_s, e, LANE_CHANGE)[0] for e in result.estimates]
    assert replayed == result.commands
    first.reset()
    again = [first.step(e.t_s, e, LANE_CHANGE)[0] for e in result.estimates]
    assert again == result.commands


def test_an_estimate_without_the_lateral_states_is_refused() -> None:
    names = ("x_m", "y_m", "yaw_rad", "vx_mps")
    estimate = Estimate(0.0, names, np.array([0.0, 0.0, 0.0, 15.0]), np.eye(4))
    with pytest.raises(ConfigError, match="vy_mps, yaw_rate_radps"):
        DynamicNmpc(CONFIG).step(0.0, estimate, LANE_CHANGE)


def test_wrong_name_is_refused() -> None:
    with pytest.raises(ConfigError, match="dynamic-nmpc"):
        DynamicNmpc(dataclasses.replace(CONFIG, name="kinematic-nmpc"))
