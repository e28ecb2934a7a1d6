"""The ``dynamic-mpc`` tracker (a delta-u MPC on Rajamani's path-error model) and its path-error
model.

The model is checked against independent numpy code (the state-space coefficients of Rajamani 2012,
sec. 2.5, written out here, discretised exactly with ``scipy.linalg.expm``) and against the
world-frame bicycle projected onto a path (the sign conventions). The tracker runs alone on
its own model: the plain-numpy linear-tyre bicycle of :mod:`tests.tracker.dynamic_closed_loop`
at 2 ms with the plant's steering actuator (50 ms lag, 0.8 rad/s), a perfect estimate every
50 ms.
"""

from __future__ import annotations

import collections
import dataclasses
import math

import numpy as np
import pytest
from scipy.linalg import expm

from cosim.core.config_fields import from_dict
from cosim.core.exceptions import ConfigError
from cosim.core.records import Command, Estimate, Plan
from tests.named_vectors import named_vector
from tests.tracker.contract import assert_commands_within_bounds, assert_every_solve_succeeded
from tests.tracker.dynamic_closed_loop import (
    ESTIMATE_NAMES,
    Actuator,
    Car,
    ClosedLoopResult,
    advance,
    estimate_of,
    run_closed_loop,
)
from tracker.config import TrackerConfig
from tracker.models.dynamic_bicycle import DynamicBicycleParams
from tracker.models.path_error_bicycle import (
    INPUT,
    INPUT_NAMES,
    STATE,
    STATE_NAMES,
    PathErrorParams,
    continuous_function,
    discrete_function,
)
from tracker.mpc.dynamic_mpc import DynamicMpc
from tracker.paths.double_lane_change import double_lane_change
from tracker.paths.reference_path import ReferencePath, wrap_angle
from tracker.registry import make_tracker

CONFIG = from_dict(TrackerConfig, {"name": "dynamic-mpc"})
"""The defaults: the reference design's Np = 10, Nc = 2, Ts = 0.1 s, the tuned weights."""
SETTINGS = CONFIG.dynamic_mpc
MODEL = PathErrorParams.from_vehicle(CONFIG.model, SETTINGS.accel_time_constant_s)
CAR = DynamicBicycleParams.from_vehicle(CONFIG.model, CONFIG.model.cornering_stiffness_front_npr,
                                        CONFIG.model.cornering_stiffness_rear_npr)
"""The bench car is the belief: the controller's own model."""
LANE_CHANGE = double_lane_change(20.0, 1.5)
STRAIGHT = ReferencePath(np.linspace(0.0, 400.0, 401), np.zeros(401), 20.0)
MAX_STEER_RAD = CONFIG.max_steer_rad
"""dynamic-mpc's default steering bound: the reference design's 15 deg."""


def circle(radius_m: float, speed_mps: float) -> ReferencePath:
    """Three quarters of a counter-clockwise circle from the origin, heading east."""
    angle = np.linspace(0.0, 1.5 * np.pi, 800)
    return ReferencePath(radius_m * np.sin(angle), radius_m * (1.0 - np.cos(angle)), speed_mps)


def seconds(result: ClosedLoopResult) -> np.ndarray:
    """Time of every physics step of a closed-loop run (2 ms)."""
    return np.arange(result.cte_m.size) * 0.002


# ---------------------------------------------------------------------------- the model


def textbook_matrices(speed_mps: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``x' = A x + B u + E psi_D'`` written out from the textbook coefficients (Rajamani 2012,
    sec. 2.5:
    a11 ... b21 of the linear-tyre bicycle), with the ISO 8855 errors of (P5)-(P6)."""
    m, i_z = CAR.mass_kg, CAR.yaw_inertia_kgm2
    l_f, l_r = CAR.cog_front_m, CAR.cog_rear_m
    c_f, c_r = CAR.cornering_stiffness_front_npr, CAR.cornering_stiffness_rear_npr
    v = speed_mps
    a = np.zeros((6, 6))
    b = np.zeros((6, 2))
    e = np.zeros((6, 1))
    vy, r, vx, ax, e1, e2 = (STATE[n] for n in STATE_NAMES)
    a[vy, vy] = -(c_f + c_r) / (m * v)
    a[vy, r] = (l_r * c_r - l_f * c_f) / (m * v) - v
    a[r, vy] = (l_r * c_r - l_f * c_f) / (i_z * v)
    a[r, r] = -(l_f**2 * c_f + l_r**2 * c_r) / (i_z * v)
    b[vy, INPUT["steer_rad"]] = c_f / m
    b[r, INPUT["steer_rad"]] = l_f * c_f / i_z
    a[vx, ax] = 1.0
    a[ax, ax] = -1.0 / MODEL.accel_time_constant_s
    b[ax, INPUT["accel_mps2"]] = 1.0 / MODEL.accel_time_constant_s
    a[e1, vy] = 1.0
    a[e1, e2] = v
    a[e2, r] = 1.0
    e[e2, 0] = -1.0
    return a, b, e


@pytest.mark.parametrize("speed_mps", [8.0, 15.0, 25.0])
def test_continuous_model_is_the_seed_state_space(speed_mps: float) -> None:
    a, b, e = textbook_matrices(speed_mps)
    f = continuous_function(MODEL)
    rng = np.random.default_rng(1)
    for _ in range(5):
        x, u, psi = rng.normal(size=6), rng.normal(size=2) * 0.1, rng.normal() * 0.1
        expected = a @ x + b @ u + e[:, 0] * psi
        assert np.asarray(f(x, u, speed_mps, psi)).ravel() == pytest.approx(expected, abs=1e-9)


@pytest.mark.parametrize("speed_mps", [4.0, 8.0, 15.0, 25.0])
def test_discrete_model_is_the_exact_zero_order_hold(speed_mps: float) -> None:
    # exp([[A, B, E], [0, 0, 0]] Ts) holds the inputs and the desired yaw rate over Ts.
    # RK4 with h |lambda| <= 0.5 errs by at most (0.5)^5 / 120 = 2.6e-4 per substep in
    # the fastest mode (reached at v_low = 4 m/s: 1.1e-4 measured; 3e-6 at 25 m/s).
    a, b, e = textbook_matrices(speed_mps)
    ts = SETTINGS.sample_time_s
    n_x, n_w = 6, 3
    augmented = np.zeros((n_x + n_w, n_x + n_w))
    augmented[:n_x, :n_x] = a
    augmented[:n_x, n_x:] = np.hstack((b, e))
    transition = expm(augmented * ts)[:n_x]
    step = discrete_function(MODEL, ts)
    rng = np.random.default_rng(2)
    for _ in range(5):
        x, u, psi = rng.normal(size=6), rng.normal(size=2) * 0.1, rng.normal() * 0.1
        held = np.concatenate((x, u, [psi]))
        model = np.asarray(step(x, u, speed_mps, psi)).ravel()
        assert np.max(np.abs(model - transition @ held)) < 2.6e-4 * np.max(np.abs(held))


def test_errors_follow_the_world_frame_car_projected_on_the_path() -> None:
    # ISO 8855 signs: the world-frame bicycle, left of a left-hand circle and pointing
    # left of its tangent, steering left; after 0.3 s the path model (linearised at the
    # speed, psi_D' = v / R) predicts its projected errors (which moved by 75 mm and
    # -9 mrad) to within what (P5)-(P6) neglect: the path speed s' is vx (1 + kappa e1
    # + ...), 0.2 % more here, so e2 drifts by about v kappa^2 e1 t = 0.1 mrad.
    radius, speed, ts = 100.0, 15.0, 0.1
    path = circle(radius, speed)
    car = Car(x_m=0.0, y_m=0.2, yaw_rad=0.02, vx_mps=speed, vy_mps=-0.05,
              yaw_rate_radps=0.12, steer_rad=0.04)
    command = Command(0.0, accel_mps2=0.0, steer_rad=0.04)
    ideal = Actuator(time_constant_s=0.0, max_rate_radps=100.0)
    start = path.project(car.x_m, car.y_m)
    x = named_vector(STATE, vy_mps=car.vy_mps, yaw_rate_radps=car.yaw_rate_radps,
                     vx_mps=speed, e1_m=start.lateral_error_m,
                     e2_rad=car.yaw_rad - start.path_yaw_rad)
    assert x[STATE["e1_m"]] > 0.0 and x[STATE["e2_rad"]] > 0.0  # left of the path, pointing left
    step = discrete_function(MODEL, ts)
    u = named_vector(INPUT, steer_rad=command.steer_rad)
    for _ in range(3):
        for _ in range(50):
            car = advance(car, command, 0.002, CAR, ideal)
        x = np.asarray(step(x, u, speed, speed / radius), dtype=float).ravel()
    end = path.project(car.x_m, car.y_m)
    assert x[STATE["e1_m"]] == pytest.approx(end.lateral_error_m, abs=1e-3)
    assert x[STATE["e2_rad"]] == pytest.approx(wrap_angle(car.yaw_rad - end.path_yaw_rad),
                                               abs=2e-4)
    assert x[STATE["yaw_rate_radps"]] == pytest.approx(car.yaw_rate_radps, abs=1e-6)


# ---------------------------------------------------------------------------- closed loop


@pytest.fixture(scope="module")
def lane_change() -> ClosedLoopResult:
    """The stretched double lane change at 20 m/s from 15 m/s, 15 s (Falcone et al. 2007, stretched
    by 1.5)."""
    return run_closed_loop(DynamicMpc(CONFIG), LANE_CHANGE, Car(0.0, 0.0, 0.0, 15.0), 15.0, CAR)


def test_lane_change_beats_the_bar_on_its_own_model(lane_change: ClosedLoopResult) -> None:
    # The reference design: max lateral deviation 88 mm on its model; here 64 mm (84 mm without the
    # bench's steering lag). The errors converge to zero on the straight after the curve.
    assert np.max(np.abs(lane_change.cte_m)) < 0.07
    assert np.max(np.abs(lane_change.cte_m[-1000:])) < 1e-4
    assert lane_change.final.x_m > 250.0
    # Max steering: the reference design reports 9.5 deg with its softer tyres; this belief's
    # understeer is 2.2 deg/g, so about 4 deg.
    assert np.max(np.abs(lane_change.steer_rad)) < math.radians(5.0)


def test_lane_change_accelerates_as_the_reference_design(lane_change: ClosedLoopResult) -> None:
    # 15 -> 18.2 m/s in the first 1.1 s, at the 3 m/s^2 bound after a ramp of 0.15 s (the
    # reference design: 18.3 m/s, at the bound from the start; the ramp, weight_accel_increment,
    # keeps a rear-driven sedan on a 0.7-friction road from spinning its wheels), then
    # held at the reference speed.
    assert lane_change.vx_mps[int(1.1 / 0.002)] == pytest.approx(18.2, abs=0.05)
    reached = np.flatnonzero(lane_change.vx_mps > 19.9)[0]
    assert np.max(np.abs(lane_change.vx_mps[reached:] - 20.0)) < 0.15


def test_lane_change_solves_every_step_within_bounds(lane_change: ClosedLoopResult) -> None:
    assert_every_solve_succeeded(lane_change.plans, CONFIG)
    assert_commands_within_bounds(lane_change.commands, CONFIG)
    steer = np.array([c.steer_rad for c in lane_change.commands])
    accel = np.array([c.accel_mps2 for c in lane_change.commands])
    assert np.all(np.abs(steer) <= MAX_STEER_RAD)  # the reference design's 15 deg
    assert np.max(accel) == CONFIG.accel_max_mps2  # the bound is reached, never exceeded
    assert all(plan.status == "Optimal" for plan in lane_change.plans)


def test_plan_shapes_and_names(lane_change: ClosedLoopResult) -> None:
    plan = lane_change.plans[100]
    n_p = SETTINGS.prediction_horizon
    assert plan.state_names == ("vy_mps", "yaw_rate_radps", "vx_mps", "ax_mps2", "e1_m",
                                "e2_rad", "x_m", "y_m")
    assert plan.input_names == INPUT_NAMES == ("accel_mps2", "steer_rad")
    assert plan.states.shape == (n_p + 1, 8)
    assert plan.inputs.shape == (n_p, 2)
    assert plan.dt_s == SETTINGS.sample_time_s
    assert plan.t_s == pytest.approx(100 * 0.05)
    assert plan.solve_time_s > 0.0
    # Delta-u with Nc = 2: two moves, then the acceleration is held (the steering follows
    # the path: test_after_the_moves_the_steering_follows_the_paths_ackermann_angle).
    held = plan.inputs[SETTINGS.control_horizon - 1 :, INPUT["accel_mps2"]]
    assert np.all(held == held[0])
    command = lane_change.commands[100]
    assert (command.accel_mps2, command.steer_rad) == tuple(plan.inputs[0])
    # Without latency node 0 is the estimate in path coordinates.
    estimate = lane_change.estimates[100]
    projection = LANE_CHANGE.project(estimate["x_m"], estimate["y_m"])
    assert plan.column("e1_m")[0] == pytest.approx(projection.lateral_error_m, abs=1e-12)
    assert plan.column("e2_rad")[0] == pytest.approx(
        wrap_angle(estimate["yaw_rad"] - projection.path_yaw_rad), abs=1e-12)
    for name in ("vy_mps", "yaw_rate_radps", "vx_mps"):
        assert plan.column(name)[0] == pytest.approx(estimate[name], abs=1e-12)
    assert len(plan.to_message()["predicted_e1_m"]) == n_p + 1
    # The world positions: node 0 is the estimate's position; every node lies e1 off the
    # path, ahead of the previous one by about vx Ts.
    assert plan.column("x_m")[0] == pytest.approx(estimate["x_m"], abs=1e-6)
    assert plan.column("y_m")[0] == pytest.approx(estimate["y_m"], abs=1e-6)
    for k in range(1, n_p + 1):
        node = LANE_CHANGE.project(plan.column("x_m")[k], plan.column("y_m")[k])
        assert node.lateral_error_m == pytest.approx(plan.column("e1_m")[k], abs=1e-3)
    step_m = np.hypot(np.diff(plan.column("x_m")), np.diff(plan.column("y_m")))
    speed = plan.column("vx_mps")
    assert step_m == pytest.approx(0.5 * (speed[:-1] + speed[1:]) * plan.dt_s, rel=0.01)


def test_straight_line_from_an_offset() -> None:
    # 0.5 m left of a straight at 20 m/s. On its own model only the steering lag and the
    # steering-rate bound separate the car from the prediction, and on a straight the
    # linear model is exact for small errors, so the error decays exponentially, to no
    # offset: measured 1 mm at 2 s, 11 um at 3 s, 0.8 um at 4 s. Overshoot 12 mm (2 %).
    result = run_closed_loop(DynamicMpc(CONFIG), STRAIGHT, Car(0.0, 0.5, 0.0, 20.0), 6.0, CAR)
    t = seconds(result)
    assert np.max(np.abs(result.cte_m[t > 3.0])) < 2e-5
    assert np.max(np.abs(result.cte_m[t > 4.0])) < 2e-6
    assert np.min(result.cte_m) > -0.015
    assert_every_solve_succeeded(result.plans, CONFIG)


@pytest.mark.slow
def test_circle_is_tracked_to_a_fraction_of_a_millimetre() -> None:
    # R = 100 m at 15 m/s (0.23 g), starting on the path with the wheel straight: a
    # transient of 47 mm (the car has to build up its yaw rate), then the steady turn
    # with a constant offset of 0.25 mm (measured from 4 s on). The offset is the
    # the reference design's heading reference e2 = 0: in a steady turn the car's heading differs
    # from the path's by its side slip (3 mrad here), and the cost trades that heading error
    # against a little lateral error (8 mm at 0.5 g; 0.1 mm with weight_heading = 10).
    # A wrong sign or a missing curvature feed-forward would leave centimetres.
    result = run_closed_loop(DynamicMpc(CONFIG), circle(100.0, 15.0), Car(0.0, 0.0, 0.0, 15.0),
                             10.0, CAR)
    t = seconds(result)
    assert np.max(np.abs(result.cte_m)) < 0.06
    assert np.max(np.abs(result.cte_m[t > 4.0])) < 5e-4
    # The steady steering is the belief's: delta = L / R + K a_y (Rajamani 2012, sec. 3.5).
    steady = CAR.wheelbase_m / 100.0 + CAR.understeer_gradient_radpmps2 * 15.0**2 / 100.0
    assert result.steer_rad[-1] == pytest.approx(steady, rel=1e-3)


def test_soft_limits_keep_the_qp_feasible_two_metres_off() -> None:
    # 2 m off the path, four times the reference design's |e1| <= 0.5 m: every QP still solves (the
    # limits are soft, one slack per node) and the car comes back with one overshoot
    # (measured 0.15 m; 0.48 m with one slack over the whole horizon), 0.7 mm at 3 s.
    result = run_closed_loop(DynamicMpc(CONFIG), STRAIGHT, Car(0.0, 2.0, 0.0, 20.0), 8.0, CAR)
    t = seconds(result)
    assert_every_solve_succeeded(result.plans, CONFIG)
    assert abs(result.plans[0].column("e1_m")[1]) > SETTINGS.max_lateral_error_m
    assert np.max(np.abs(result.cte_m[t > 3.0])) < 0.001
    assert np.min(result.cte_m) > -0.2
    assert_commands_within_bounds(result.commands, CONFIG)


class DelayedTracker:
    """The tracker seen through a transport delay of whole control periods."""

    def __init__(self, tracker: DynamicMpc, periods: int) -> None:
        self.tracker = tracker
        self.queue: collections.deque[Command] = collections.deque(
            Command(0.0, 0.0, 0.0) for _ in range(periods))

    def step(self, t_s: float, estimate: Estimate,
             reference: ReferencePath) -> tuple[Command, Plan]:
        command, plan = self.tracker.step(t_s, estimate, reference)
        self.queue.append(command)
        return self.queue.popleft(), plan


def _steer_after_control_horizon(mode: str) -> TrackerConfig:
    return dataclasses.replace(CONFIG, dynamic_mpc=dataclasses.replace(
        SETTINGS, steer_after_control_horizon=mode))


def test_after_the_moves_the_steering_follows_the_paths_ackermann_angle(
        lane_change: ClosedLoopResult) -> None:
    """From stage Nc on, every plan's steering keeps its offset from ``atan(L kappa)`` at
    the stage's middle (the curvature read here where the plan's own positions project,
    to 1e-3 rad: the tracker reads it at the arc lengths it expects), while it turns by up
    to 0.03 rad and more across a swerve; with ``held`` (the reference design) it is
    constant, and on a straight it is constant either way."""
    n_c, wheelbase_m = SETTINGS.control_horizon, CONFIG.model.wheelbase_m
    largest_turn = 0.0
    for plan in lane_change.plans:
        x_m, y_m = plan.column("x_m"), plan.column("y_m")
        middles = [LANE_CHANGE.project(x, y).s_m for x, y in
                   zip(0.5 * (x_m[:-1] + x_m[1:]), 0.5 * (y_m[:-1] + y_m[1:]), strict=True)]
        ackermann = np.arctan(wheelbase_m * LANE_CHANGE.sample(np.array(middles))[
            "curvature_1pm"])
        steer = plan.column("steer_rad")[n_c - 1:]
        assert steer - steer[0] == pytest.approx(ackermann[n_c - 1:] - ackermann[n_c - 1],
                                                 abs=1e-3)
        largest_turn = max(largest_turn, float(np.ptp(steer)))
    assert largest_turn > 0.03
    held = run_closed_loop(DynamicMpc(_steer_after_control_horizon("held")), LANE_CHANGE,
                           Car(0.0, 0.0, 0.0, 15.0), 3.0, CAR)
    for plan in held.plans:
        assert np.all(plan.inputs[n_c - 1:] == plan.inputs[n_c - 1])
    straight = run_closed_loop(DynamicMpc(CONFIG), STRAIGHT, Car(0.0, 0.5, 0.0, 20.0), 2.0,
                               CAR)
    for plan in straight.plans:
        assert np.all(plan.inputs[n_c - 1:] == plan.inputs[n_c - 1])


@pytest.mark.slow
def test_latency_compensation_through_the_delay_line() -> None:
    # A 100 ms transport delay. Predicting over it with the commands in flight (the exact
    # ones, on its own model) gives back the tracking without delay: 64.1 mm against
    # 64.0 mm; without the prediction 123 mm. With the reference design's held input:
    # steering that follows the path after the moves leads the bends, and makes up for
    # part of an uncompensated delay (53 mm).
    errors = {}
    for compensate in (True, False):
        config = dataclasses.replace(_steer_after_control_horizon("held"), latency_s=0.1,
                                     latency_compensation=compensate)
        result = run_closed_loop(DelayedTracker(DynamicMpc(config), 2), LANE_CHANGE,
                                 Car(0.0, 0.0, 0.0, 15.0), 9.0, CAR)
        errors[compensate] = np.max(np.abs(result.cte_m))
    assert errors[True] < 0.065
    assert errors[False] > 0.1


# ---------------------------------------------------------------------------- failures


def test_non_finite_estimate_falls_back_then_stops_safely() -> None:
    tracker = DynamicMpc(CONFIG)
    car = Car(0.0, 0.0, 0.0, 15.0)
    _, good = tracker.step(0.0, estimate_of(0.0, car), LANE_CHANGE)
    assert good.success and not good.fallback and good.iterations > 0
    nan = Estimate(0.0, ESTIMATE_NAMES, np.full(len(ESTIMATE_NAMES), np.nan),
                   np.eye(len(ESTIMATE_NAMES)))
    plans, commands = [], []
    for i in range(1, 21):
        t_s = i * 0.05
        command, plan = tracker.step(t_s, dataclasses.replace(nan, t_s=t_s), LANE_CHANGE)
        plans.append(plan)
        commands.append(command)
    assert all(p.fallback and not p.success and math.isnan(p.cost) for p in plans)
    assert all("non_finite_estimate" in p.status for p in plans)
    replaying = [p for p in plans if p.t_s - 0.05 <= CONFIG.fallback_time_s + 1e-9]
    assert len(replaying) == 11 and all(p.status.startswith("fallback") for p in replaying)
    # The last good plan, shifted by the elapsed time (Ts = 0.1 s: one row per 2 steps).
    first = commands[0]
    assert (first.accel_mps2, first.steer_rad) == tuple(good.inputs[0])
    stopping = list(zip(commands[11:], plans[11:], strict=True))
    assert stopping and all(p.status.startswith("safe_stop") for _, p in stopping)
    assert all(c.accel_mps2 == CONFIG.safe_stop_accel_mps2 for c, _ in stopping)
    assert all(c.steer_rad == 0.0 for c, _ in stopping)
    # A good estimate ends the safe stop.
    _, again = tracker.step(1.05, estimate_of(1.05, car), LANE_CHANGE)
    assert again.success and not again.fallback


def test_failed_qp_falls_back_without_raising() -> None:
    config = dataclasses.replace(CONFIG, dynamic_mpc=dataclasses.replace(SETTINGS,
                                                                         max_iterations=1))
    tracker = DynamicMpc(config)
    tracker.reset(Command(0.0, accel_mps2=0.5, steer_rad=0.05))
    car = Car(0.0, 0.5, 0.0, 15.0)
    for i in range(3):
        command, plan = tracker.step(i * 0.05, estimate_of(i * 0.05, car), LANE_CHANGE)
        assert plan.fallback and not plan.success
        assert plan.status.startswith("fallback (") and "limit" in plan.status.lower()
        assert (command.accel_mps2, command.steer_rad) == (0.5, 0.05)  # held: no good plan
        assert np.all(np.isfinite(plan.states))


@pytest.mark.slow
def test_same_inputs_give_identical_commands() -> None:
    first = DynamicMpc(CONFIG)
    result = run_closed_loop(first, LANE_CHANGE, Car(0.0, 0.3, 0.02, 15.0), 3.0, CAR)
    second = DynamicMpc(CONFIG)
    assert [second.step(e.t_s, e, LANE_CHANGE)[0] for e in result.estimates] == result.commands
    first.reset()
    assert [first.step(e.t_s, e, LANE_CHANGE)[0] for e in result.estimates] == result.commands


def test_back_ends_agree() -> None:
    # HiGHS (the default, reports iterations) and DAQP (faster, reports none) solve the
    # same QPs: equal commands to QP tolerance, and DAQP's plans say 0 iterations.
    highs = DynamicMpc(CONFIG)
    result = run_closed_loop(highs, LANE_CHANGE, Car(0.0, 0.3, 0.02, 15.0), 2.0, CAR)
    settings = dataclasses.replace(SETTINGS, qp_solver="daqp")
    daqp = DynamicMpc(dataclasses.replace(CONFIG, dynamic_mpc=settings))
    for estimate, command in zip(result.estimates, result.commands, strict=True):
        other, plan = daqp.step(estimate.t_s, estimate, LANE_CHANGE)
        assert plan.success and plan.status == "optimal" and plan.iterations == 0
        assert other.steer_rad == pytest.approx(command.steer_rad, abs=1e-6)
        assert other.accel_mps2 == pytest.approx(command.accel_mps2, abs=1e-6)


# ---------------------------------------------------------------------------- configuration


def test_control_horizon_beyond_prediction_horizon_is_refused() -> None:
    with pytest.raises(ConfigError, match=r"dynamic_mpc\.control_horizon = 11: expected at "
                                          r"most prediction_horizon = 10"):
        from_dict(TrackerConfig, {"name": "dynamic-mpc", "dynamic_mpc": {"control_horizon": 11}})


def test_unknown_qp_solver_is_refused() -> None:
    with pytest.raises(ConfigError, match=r"dynamic_mpc\.qp_solver = 'ipopt'"):
        from_dict(TrackerConfig, {"dynamic_mpc": {"qp_solver": "ipopt"}})


def test_wrong_name_and_missing_states_are_refused() -> None:
    with pytest.raises(ConfigError, match="dynamic-mpc"):
        DynamicMpc(dataclasses.replace(CONFIG, name="dynamic-nmpc"))
    names = ("x_m", "y_m", "yaw_rad", "vx_mps")
    estimate = Estimate(0.0, names, np.array([0.0, 0.0, 0.0, 15.0]), np.eye(4))
    with pytest.raises(ConfigError, match="vy_mps, yaw_rate_radps"):
        DynamicMpc(CONFIG).step(0.0, estimate, LANE_CHANGE)


def test_registry_builds_it() -> None:
    assert isinstance(make_tracker(CONFIG), DynamicMpc)


def test_the_speed_reference_is_previewed_over_the_horizon() -> None:
    """A profile that drops ahead of the car is braked for before the car gets there: the
    QP reads the profile where each node is expected (held at the start's speed, the car
    would coast on until the drop reached it)."""
    from tracker.paths.speed_profile import SpatialSpeed  # noqa: PLC0415

    drop = SpatialSpeed(np.array([0.0, 12.0, 20.0, 400.0]), np.array([20.0, 20.0, 10.0, 10.0]))
    path = ReferencePath(np.linspace(0.0, 400.0, 401), np.zeros(401), drop)
    tracker = DynamicMpc(CONFIG)
    command, plan = tracker.step(0.0, estimate_of(0.0, Car(0.0, 0.0, 0.0, 20.0)), path)
    assert plan.success
    assert command.accel_mps2 < -0.5  # braking now, at s = 0 where the profile is still 20
