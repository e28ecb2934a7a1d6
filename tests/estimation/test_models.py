"""The filters' process and measurement models: Jacobians, process noise, the bicycle, by hand.

Hand-derived references: finite differences for every Jacobian (as pink's
``tests/test_jacobians.py`` does), scipy's matrix exponential for the process noise (Van
Loan 1978), the tracker's own dynamic bicycle (``tracker.models.dynamic_bicycle``: its state-space
matrices and steady turn) for the lateral dynamics, and numbers one can check by hand.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import scipy.linalg

from cosim.core.vehicle_params import VehicleParams
from cosim.plant.sedan_model import ackermann_angles
from estimation.belief_models import process_noise, roll_params
from estimation.bicycle import (
    LOW_SPEED_MPS,
    TYRE_MODELS,
    BicycleParams,
    RollParams,
    slip_speed,
)
from estimation.config import EstimatorConfig
from estimation.measurement_models import build_measurement_models
from estimation.process_model import ProcessModel
from estimation.state import STATE_NAMES, state_index, wrap_angle
from tracker.models.dynamic_bicycle import DynamicBicycleParams

CONFIG = EstimatorConfig()
NOISE = process_noise(CONFIG)
BELIEF = VehicleParams()
ROLL = roll_params(CONFIG, BELIEF)
SENSORS = ("gnss", "gnss_velocity", "imu", "wheel_speed", "steering", "heading")


def _process(tyre_model: str = "saturating", roll: RollParams | None = ROLL,
             load_sensitivity: tuple[float, float] = (0.0, 0.0),
             relaxation_lengths_m: tuple[float, float] = (0.0, 0.0)) -> ProcessModel:
    return ProcessModel(
        NOISE, BicycleParams.from_vehicle(BELIEF, tyre_model, roll, load_sensitivity,
                                          relaxation_lengths_m),
        CONFIG.lateral_residual_time_constant_s,
    )


@pytest.fixture(scope="module", params=TYRE_MODELS)
def process(request: pytest.FixtureRequest) -> ProcessModel:
    """The filters' process model with the configured body roll, load transfer and tyre
    relaxation."""
    return _process(request.param, load_sensitivity=CONFIG.tyre_load_sensitivities,
                    relaxation_lengths_m=CONFIG.tyre_relaxation_lengths_m)


@pytest.fixture(scope="module")
def linear_process() -> ProcessModel:
    """Linear tyres, no body roll: the textbook dynamic bicycle."""
    return _process("linear", roll=None)


def _state(**values: float) -> np.ndarray:
    x = np.zeros(len(STATE_NAMES))
    x[state_index("rolling_radius_scale")] = 1.0
    x[state_index("wheel_track_scale")] = 1.0
    for name, value in values.items():
        x[state_index(name)] = value
    return x


def _random_states(count: int, seed: int) -> list[np.ndarray]:
    """States over the whole envelope: yaw near +-pi, zero yaw rate, standstill, reversing,
    the low-speed blend, saturated tyres."""
    rng = np.random.default_rng(seed)
    states = [
        _state(x_m=3.0, y_m=-2.0, yaw_rad=math.pi - 1e-3, vx_mps=20.0, yaw_rate_radps=0.0),
        _state(yaw_rad=-math.pi + 1e-3, vx_mps=0.0, vy_mps=0.3, yaw_rate_radps=-0.4),
        _state(vx_mps=2.0, vy_mps=-0.5, yaw_rate_radps=0.5, steer_rad=0.3),
        _state(vx_mps=25.0, vy_mps=-3.0, yaw_rate_radps=0.6, steer_rad=0.2),
    ]
    for _ in range(count):
        states.append(
            _state(
                x_m=rng.uniform(-100, 100),
                y_m=rng.uniform(-100, 100),
                yaw_rad=rng.uniform(-math.pi, math.pi),
                vx_mps=rng.uniform(-5, 40),
                vy_mps=rng.uniform(-2, 2),
                yaw_rate_radps=rng.uniform(-1, 1),
                ax_mps2=rng.uniform(-8, 4),
                steer_rad=rng.uniform(-0.4, 0.4),
                roll_rad=rng.uniform(-0.08, 0.08),
                roll_rate_radps=rng.uniform(-0.5, 0.5),
                lateral_accel_residual_mps2=rng.uniform(-2, 2),
                gyro_bias_radps=rng.uniform(-0.01, 0.01),
                ax_bias_mps2=rng.uniform(-0.1, 0.1),
                rolling_radius_scale=rng.uniform(0.95, 1.05),
            )
        )
    # Keep away from the kink-free but piecewise blend point of slip_speed (C1 only).
    return [s for s in states if abs(s[state_index("vx_mps")] - LOW_SPEED_MPS) > 1e-3]


def _finite_difference(function, x: np.ndarray, eps: float = 1e-6) -> np.ndarray:
    """Central differences of a vector function, one column per state."""
    columns = []
    for i in range(len(x)):
        step = np.zeros_like(x)
        step[i] = eps
        columns.append((function(x + step) - function(x - step)) / (2 * eps))
    return np.column_stack(columns)


def test_state_names_are_unique_and_named() -> None:
    assert len(set(STATE_NAMES)) == len(STATE_NAMES)
    assert set(STATE_NAMES) >= {
        "x_m", "y_m", "yaw_rad", "vx_mps", "vy_mps", "yaw_rate_radps", "ax_mps2", "steer_rad",
        "gyro_bias_radps",
    }
    with pytest.raises(KeyError, match="unknown state"):
        state_index("speed")


def test_cornering_stiffness_comes_from_the_belief() -> None:
    bicycle = BicycleParams.from_vehicle(VehicleParams())
    assert bicycle.cornering_stiffness_front_npr == pytest.approx(72550.0)
    assert bicycle.cornering_stiffness_rear_npr == pytest.approx(79580.0)
    assert bicycle.tyre_friction == VehicleParams().tyre_friction
    with pytest.raises(ValueError, match="tyre_model"):
        BicycleParams.from_vehicle(VehicleParams(), "magic")
    with pytest.raises(ValueError, match="mass_kg"):
        BicycleParams(0.0, 1.0, 1.0, 1.0, 1.0, 1.0)


@pytest.mark.parametrize("dt_s", [0.001, 0.01, 0.02])
def test_process_jacobian_matches_finite_differences(process: ProcessModel, dt_s: float) -> None:
    for x in _random_states(20, seed=1):
        _, transition, _ = process.step(x, dt_s)
        numeric = _finite_difference(lambda s: process.step(s, dt_s)[0].reshape(-1), x)
        np.testing.assert_allclose(transition, numeric, rtol=1e-6, atol=1e-7)


def test_continuous_jacobian_matches_finite_differences(process: ProcessModel) -> None:
    for x in _random_states(20, seed=2):
        _, a = process.derivative(x)
        numeric = _finite_difference(lambda s: process.derivative(s)[0], x)
        np.testing.assert_allclose(a, numeric, rtol=1e-6, atol=1e-6)


def _van_loan(a: np.ndarray, w: np.ndarray, dt_s: float) -> np.ndarray:
    """Discrete process noise of dx = A x dt + dw, E[dw dw'] = W dt (Van Loan 1978)."""
    n = a.shape[0]
    block = np.zeros((2 * n, 2 * n))
    block[:n, :n] = -a
    block[:n, n:] = w
    block[n:, n:] = a.T
    exponential = scipy.linalg.expm(block * dt_s)
    transition = exponential[n:, n:].T
    return transition @ exponential[:n, n:]


@pytest.mark.parametrize("dt_s", [0.002, 0.01, 0.02])
def test_process_noise_is_the_van_loan_integral(process: ProcessModel, dt_s: float) -> None:
    for x in _random_states(10, seed=3):
        _, _, q = process.step(x, dt_s)
        np.testing.assert_array_equal(process.process_noise(x, dt_s), q)
        _, a = process.derivative(x)
        reference = _van_loan(a, process.noise_psd(x), dt_s)
        scale = np.sqrt(np.outer(np.diag(reference), np.diag(reference))) + 1e-300
        np.testing.assert_allclose(q / scale, reference / scale, atol=1e-9)
        np.testing.assert_array_equal(q, q.T)
        assert np.linalg.eigvalsh(q).min() > -1e-15


def test_noise_psd_grows_with_the_tyre_forces(process: ProcessModel) -> None:
    """Straight ahead the PSDs are the configured constants; in a turn the residual's grows by
    ``2 eps^2 / tau * a_y^2``, the heading's by ``yaw_transient_psd_s3 * r'^2`` and the roll
    acceleration's by ``roll_accel_relative_psd_s * (omega^2 G a_y)^2``, with ``a_y`` and
    ``r'`` the bicycle's own (from its derivative at that state)."""
    straight = _state(vx_mps=20.0)
    np.testing.assert_array_equal(process.noise_psd(straight), NOISE.diagonal())
    turning = _state(vx_mps=20.0, steer_rad=0.03)
    w = np.diag(process.noise_psd(turning)) - np.diag(NOISE.diagonal())
    derivative, _ = process.derivative(turning)
    yaw_accel = derivative[state_index("yaw_rate_radps")]
    # Level and at rest in roll, the roll mode is driven by omega^2 G a_y alone: (R2).
    roll = process.bicycle.roll
    commanded = derivative[state_index("roll_rate_radps")]
    lateral = commanded / (roll.angular_frequency_radps**2 * roll.gradient_radpmps2)
    assert lateral > 1.0 and abs(yaw_accel) > 0.5
    expected = {
        "lateral_accel_residual_mps2": (2.0 * CONFIG.lateral_residual_relative**2
                                        / CONFIG.lateral_residual_time_constant_s * lateral**2),
        "yaw_rad": CONFIG.yaw_transient_psd_s3 * yaw_accel**2,
        "roll_rate_radps": CONFIG.roll_accel_relative_psd_s * commanded**2,
    }
    for name, value in expected.items():
        assert w[state_index(name)] == pytest.approx(value, rel=1e-9), name
    others = [i for i, n in enumerate(STATE_NAMES) if n not in expected]
    np.testing.assert_array_equal(w[others], 0.0)


def test_the_yaw_moment_noise_grows_with_each_axles_moment() -> None:
    """With ``yaw_moment_relative_psd_s`` the yaw acceleration's PSD grows by it times
    ``((l_f F_f)^2 + (l_r F_r)^2) / I_z^2``, the axles' forces those of the bicycle's own
    derivative (its lateral acceleration and yaw acceleration give both); straight ahead
    it adds nothing."""
    relative_s = 0.3
    noise = dataclasses.replace(NOISE, yaw_moment_relative_psd_s=relative_s)
    bicycle = BicycleParams.from_vehicle(BELIEF, roll=ROLL)
    process = ProcessModel(noise, bicycle, CONFIG.lateral_residual_time_constant_s)
    straight = _state(vx_mps=20.0)
    np.testing.assert_array_equal(process.noise_psd(straight), noise.diagonal())
    turning = _state(vx_mps=20.0, vy_mps=-0.2, yaw_rate_radps=0.25, steer_rad=0.03)
    moments = _axle_moments(process, turning)
    w = np.diag(process.noise_psd(turning))
    without = np.diag(ProcessModel(NOISE, bicycle, CONFIG.lateral_residual_time_constant_s)
                      .noise_psd(turning))
    yaw_rate = state_index("yaw_rate_radps")
    assert np.abs(moments).min() > 0.5
    assert w[yaw_rate] - without[yaw_rate] == pytest.approx(
        relative_s * float(moments @ moments), rel=1e-9)
    others = [i for i in range(len(STATE_NAMES)) if i != yaw_rate]
    np.testing.assert_array_equal(w[others], without[others])


def test_the_load_transfer_noise_grows_with_braking_in_a_turn_only() -> None:
    """With ``yaw_moment_load_transfer_psd_s5pm2`` the yaw acceleration's PSD grows by it
    times ``a_x^2 ((l_f F_f)^2 + (l_r F_r)^2) / I_z^2``: nothing in a turn at constant speed
    or braking straight ahead, something driving in the turn too, and at twice the
    deceleration about four times as much (the moments change a little with the load)."""
    coefficient = 3.0
    noise = dataclasses.replace(NOISE, yaw_moment_load_transfer_psd_s5pm2=coefficient)
    bicycle = BicycleParams.from_vehicle(BELIEF, roll=ROLL)
    process = ProcessModel(noise, bicycle, CONFIG.lateral_residual_time_constant_s)
    without = ProcessModel(NOISE, bicycle, CONFIG.lateral_residual_time_constant_s)
    turn = {"vx_mps": 20.0, "vy_mps": -0.2, "yaw_rate_radps": 0.25, "steer_rad": 0.03}
    for state in (_state(**turn), _state(vx_mps=20.0, ax_mps2=-2.0)):
        np.testing.assert_array_equal(process.noise_psd(state), without.noise_psd(state))
    yaw_rate = state_index("yaw_rate_radps")
    added = {}
    for ax_mps2 in (-2.0, 2.0, -4.0):
        state = _state(**turn, ax_mps2=ax_mps2)
        w, w0 = np.diag(process.noise_psd(state)), np.diag(without.noise_psd(state))
        others = [i for i in range(len(STATE_NAMES)) if i != yaw_rate]
        np.testing.assert_array_equal(w[others], w0[others])
        added[ax_mps2] = w[yaw_rate] - w0[yaw_rate]
    # The axles' moments of the braking turn (the load moved forward changes them).
    moments = _axle_moments(process, _state(**turn, ax_mps2=-2.0))
    assert np.abs(moments).min() > 0.5
    assert added[-2.0] == pytest.approx(coefficient * 4.0 * float(moments @ moments),
                                        rel=1e-9)
    assert added[2.0] > 0.0 and added[-4.0] > 3.0 * added[-2.0]


def _axle_moments(process: ProcessModel, state: np.ndarray) -> np.ndarray:
    """``(l_f F_f, l_r F_r) / I_z`` of ``state``, the axles' forces found from the bicycle's
    own derivative: ``F_f + F_r = m a_t`` and ``l_f F_f - l_r F_r = I_z r'``, with the tyres'
    lateral acceleration ``a_t`` as the roll mode's drive shows it (R2: ``p' = omega^2 G a_t``
    at zero roll and roll rate)."""
    bicycle = process.bicycle
    roll = bicycle.roll
    derivative, _ = process.derivative(state)
    lateral = derivative[state_index("roll_rate_radps")] / (
        roll.angular_frequency_radps**2 * roll.gradient_radpmps2)
    yaw_accel = derivative[state_index("yaw_rate_radps")]
    forces = np.linalg.solve(
        [[1.0, 1.0], [bicycle.cog_front_m, -bicycle.cog_rear_m]],
        [bicycle.mass_kg * lateral, bicycle.yaw_inertia_kgm2 * yaw_accel])
    return forces * [bicycle.cog_front_m, bicycle.cog_rear_m] / bicycle.yaw_inertia_kgm2


def test_the_jerk_noise_grows_with_the_longitudinal_acceleration(process: ProcessModel) -> None:
    """``jerk_relative_psd_1ps`` adds ``it * a_x^2`` to the jerk's PSD, the acceleration the
    state's own (launch or braking), and nothing else; cruising it adds nothing."""
    assert CONFIG.jerk_relative_psd_1ps > 0.0
    ax = state_index("ax_mps2")
    cruising = np.diag(process.noise_psd(_state(vx_mps=20.0)))
    for accel_mps2 in (2.0, -3.0):
        w = np.diag(process.noise_psd(_state(vx_mps=20.0, ax_mps2=accel_mps2)))
        assert w[ax] - cruising[ax] == pytest.approx(
            CONFIG.jerk_relative_psd_1ps * accel_mps2**2, rel=1e-12)
        others = [i for i in range(len(STATE_NAMES)) if i != ax]
        np.testing.assert_array_equal(w[others], cruising[others])


def test_process_noise_grows_with_the_interval_as_expected(process: ProcessModel) -> None:
    """Jerk noise alone: variance of ax grows as q t, of vx as q t^3 / 3 (straight line)."""
    x = _state(vx_mps=10.0)
    _, _, q = process.step(x, 0.02)
    ax, vx = state_index("ax_mps2"), state_index("vx_mps")
    assert q[ax, ax] == pytest.approx(CONFIG.jerk_psd_m2ps5 * 0.02, rel=1e-12)
    assert q[vx, vx] == pytest.approx(CONFIG.jerk_psd_m2ps5 * 0.02**3 / 3, rel=1e-12)


def test_sigma_points_propagate_like_single_states() -> None:
    mapped = ProcessModel(
        NOISE, BicycleParams.from_vehicle(BELIEF, roll=ROLL),
        CONFIG.lateral_residual_time_constant_s, sigma_point_count=5,
    )
    points = np.array(_random_states(3, seed=5)[:5])
    single = np.vstack([mapped.step(p, 0.01)[0].reshape(-1) for p in points])
    np.testing.assert_array_equal(mapped.propagate(points, 0.01), single)
    np.testing.assert_array_equal(mapped.propagate(points[:2], 0.01), single[:2])


def test_straight_line_by_hand(process: ProcessModel) -> None:
    """20 m/s for 2 s heading north-east -> 40 m along the diagonal."""
    x = _state(yaw_rad=math.pi / 4, vx_mps=20.0).reshape(-1, 1)
    for _ in range(200):
        x, _, _ = process.step(x, 0.01)
    assert x[state_index("x_m"), 0] == pytest.approx(40.0 / math.sqrt(2), abs=1e-9)
    assert x[state_index("y_m"), 0] == pytest.approx(40.0 / math.sqrt(2), abs=1e-9)
    assert x[state_index("vx_mps"), 0] == pytest.approx(20.0, abs=1e-12)
    assert x[state_index("vy_mps"), 0] == 0.0 and x[state_index("yaw_rate_radps"), 0] == 0.0


@pytest.mark.parametrize("vx_mps", [8.0, 20.0, 35.0])
def test_linearised_lateral_dynamics_match_the_trackers_bicycle(
    linear_process: ProcessModel, vx_mps: float
) -> None:
    """d(vy', r')/d(vy, r, delta) at a straight run equals the textbook a11 .. b21 as
    tracker.models.dynamic_bicycle writes them (an independent implementation of the same model)."""
    reference = DynamicBicycleParams.from_vehicle(BELIEF, 72550.0, 79580.0)
    a_ref, b_ref = reference.lateral_state_space(vx_mps)
    for process in (linear_process, _process("saturating", roll=None)):  # same slope at 0
        _, a = process.derivative(_state(vx_mps=vx_mps))
        rows = [state_index("vy_mps"), state_index("yaw_rate_radps")]
        np.testing.assert_allclose(a[np.ix_(rows, rows)], a_ref, rtol=1e-12)
        np.testing.assert_allclose(a[rows, state_index("steer_rad")], b_ref[:, 0], rtol=1e-12)
        # The residual is a lateral acceleration: it enters vy' with gain one.
        assert a[rows[0], state_index("lateral_accel_residual_mps2")] == 1.0


def test_steady_turn_closes_its_circle(linear_process: ProcessModel) -> None:
    """Start in the steady turn of (S2)-(S3) for 0.03 rad at 20 m/s: vy and r stay put and
    after one revolution, 2 pi / r, the car is back where it started. (The kinematic
    longitudinal acceleration of a steady turn with side slip is ``ax = -r vy``.)"""
    reference = DynamicBicycleParams.from_vehicle(BELIEF, 72550.0, 79580.0)
    steady = reference.steady_state(20.0, 0.03)
    vy, r = steady["vy_mps"], steady["yaw_rate_radps"]
    x = _state(vx_mps=20.0, vy_mps=vy, yaw_rate_radps=r, steer_rad=0.03, ax_mps2=-r * vy)
    f, _ = linear_process.derivative(x)
    for name in ("vy_mps", "yaw_rate_radps", "vx_mps"):
        assert f[state_index(name)] == pytest.approx(0.0, abs=1e-10)
    period_s = 2 * math.pi / steady["yaw_rate_radps"]
    steps = math.ceil(period_s / 0.01)
    state = x.reshape(-1, 1)
    for _ in range(steps):
        state, _, _ = linear_process.step(state, period_s / steps)
    assert state[state_index("x_m"), 0] == pytest.approx(0.0, abs=1e-6)
    assert state[state_index("y_m"), 0] == pytest.approx(0.0, abs=1e-6)
    assert wrap_angle(state[state_index("yaw_rad"), 0]) == pytest.approx(0.0, abs=1e-9)


def test_roll_mode_by_hand() -> None:
    """Under a steady lateral acceleration the body rolls by G a_y and stays there:
    0.01 rad/(m/s^2) at 5 m/s^2 is 0.05 rad (2.9 deg); the tyres see the axles' lateral
    velocity vy + h p, the CoG being 0.55 m above the roll axis."""
    assert ROLL.gradient_radpmps2 == CONFIG.roll_gradient_radpmps2
    assert ROLL.sway_arm_m == BELIEF.cog_height_m
    process = _process("linear")
    # a_t = 5 m/s^2 (from the residual state alone: the tyres at zero slip), the body at
    # its steady roll, not rolling.
    x = _state(vx_mps=20.0, lateral_accel_residual_mps2=5.0,
               roll_rad=CONFIG.roll_gradient_radpmps2 * 5.0)
    f, a = process.derivative(x)
    assert f[state_index("roll_rate_radps")] == pytest.approx(0.0, abs=1e-12)
    assert f[state_index("roll_rad")] == 0.0
    omega = 2 * math.pi * CONFIG.roll_frequency_hz
    # d(roll acceleration)/d(roll) = -omega^2; d/d(roll rate) includes -2 zeta omega.
    assert a[state_index("roll_rate_radps"), state_index("roll_rad")] == pytest.approx(-omega**2)
    # The IMU at the CoG sees the tyres' 5 m/s^2 (no sway acceleration in a steady roll).
    imu = build_measurement_models(
        BELIEF, 0.05, 0.5, bicycle=BicycleParams.from_vehicle(BELIEF, "linear", ROLL))["imu"]
    assert imu.evaluate(x)[0][2] == pytest.approx(5.0, rel=1e-12)
    # Rolling at 0.1 rad/s: the CoG moves 0.055 m/s sideways relative to the axles, so
    # the same tyre forces need vy 0.055 m/s lower.
    rolling = _state(vx_mps=20.0, vy_mps=-0.055, roll_rate_radps=0.1)
    still = _state(vx_mps=20.0)
    assert imu.evaluate(rolling)[0][2] - imu.evaluate(still)[0][2] == pytest.approx(
        -BELIEF.cog_height_m * (-2 * CONFIG.roll_damping_ratio * omega * 0.1), rel=1e-9)


def test_saturating_tyres_limit_the_force_at_the_friction_circle() -> None:
    """A car sliding sideways at 20 m/s with vy = -6 m/s (17 deg): the linear tyres would
    push at 1.4 g; the saturating ones stay below mu g = 1 g."""
    model = build_measurement_models(BELIEF, 0.05, 0.5)["imu"]
    linear = build_measurement_models(
        BELIEF, 0.05, 0.5, bicycle=BicycleParams.from_vehicle(BELIEF, "linear"))["imu"]
    x = _state(vx_mps=20.0, vy_mps=-6.0)
    ay_linear = linear.evaluate(x)[0][2]
    ay = model.evaluate(x)[0][2]
    assert ay_linear == pytest.approx((72550.0 + 79580.0) * 0.3 / BELIEF.mass_kg)
    assert 0.9 * 9.81 < ay < 9.81 * BELIEF.tyre_friction
    # Small slips: the same force.
    x = _state(vx_mps=20.0, vy_mps=-0.05)
    assert model.evaluate(x)[0][2] == pytest.approx(linear.evaluate(x)[0][2], rel=1e-3)


def test_load_transfer_by_hand() -> None:
    """(D3''): accelerating at 1.5 m/s^2 moves ``m a_x h / L`` of load from the front axle to
    the rear; each axle's cornering stiffness follows its load ratio to its power ``eps_i``.
    The yaw acceleration of a turn, linear tyres, by hand; coasting, the static model's to
    the bit."""
    front_eps, rear_eps = 0.58, 0.74
    moving = _process("linear", roll=None, load_sensitivity=(front_eps, rear_eps))
    static = _process("linear", roll=None)
    vx, vy, r, delta, ax = 20.0, -0.3, 0.25, 0.05, 1.5
    lf, lr = BELIEF.cog_front_m, BELIEF.cog_rear_m
    wheelbase, weight = lf + lr, BELIEF.mass_kg * 9.81
    transfer = BELIEF.mass_kg * ax * BELIEF.cog_height_m / wheelbase
    front = 72550.0 * (delta - (vy + lf * r) / vx) * (
        1.0 - transfer / (weight * lr / wheelbase)) ** front_eps
    rear = 79580.0 * (-(vy - lr * r) / vx) * (
        1.0 + transfer / (weight * lf / wheelbase)) ** rear_eps
    x = _state(vx_mps=vx, vy_mps=vy, yaw_rate_radps=r, steer_rad=delta, ax_mps2=ax)
    yaw_accel = moving.derivative(x)[0][state_index("yaw_rate_radps")]
    assert yaw_accel == pytest.approx((lf * front - lr * rear) / BELIEF.yaw_inertia_kgm2,
                                      rel=1e-12)
    # Accelerating in a left turn, the heavier rear axle turns the car less.
    assert yaw_accel < static.derivative(x)[0][state_index("yaw_rate_radps")] - 0.05
    coasting = _state(vx_mps=vx, vy_mps=vy, yaw_rate_radps=r, steer_rad=delta)
    np.testing.assert_array_equal(moving.derivative(coasting)[0], static.derivative(coasting)[0])


def test_cornering_drag_by_hand() -> None:
    """The front tyres' lateral force, perpendicular to the steered wheels, along the car:
    ``-C_f alpha_f sin(delta) / m`` with linear tyres; none without steering."""
    model = _process("linear", roll=None)
    vx, vy, r, delta = 20.0, -0.3, 0.25, 0.05
    alpha_front = delta - (vy + BELIEF.cog_front_m * r) / vx
    x = _state(vx_mps=vx, vy_mps=vy, yaw_rate_radps=r, steer_rad=delta)
    assert model.cornering_drag_mps2(x) == pytest.approx(
        -72550.0 * alpha_front * math.sin(delta) / BELIEF.mass_kg, rel=1e-12)
    assert model.cornering_drag_mps2(_state(vx_mps=vx, vy_mps=vy, yaw_rate_radps=r)) == 0.0


def test_sideslip_moves_the_car_sideways(process: ProcessModel) -> None:
    """Heading east with vy = 1 m/s to the left: the CoG drifts north while the tyres pull
    vy back (rear slip angle -0.1 rad: a strong force to the right)."""
    x = _state(vx_mps=10.0, vy_mps=1.0).reshape(-1, 1)
    x_next, _, _ = process.step(x, 0.01)
    assert x_next[state_index("y_m"), 0] == pytest.approx(0.01 * 1.0, rel=0.3)
    assert x_next[state_index("vy_mps"), 0] < 1.0


def test_slip_speed_floor() -> None:
    assert float(slip_speed(20.0)) == 20.0
    assert float(slip_speed(LOW_SPEED_MPS)) == LOW_SPEED_MPS
    assert float(slip_speed(0.0)) == LOW_SPEED_MPS / 2
    assert float(slip_speed(-3.0)) == float(slip_speed(3.0))


def test_step_refuses_long_substeps(process: ProcessModel) -> None:
    with pytest.raises(ValueError, match="sub-step"):
        process.step(_state(), 0.05)
    with pytest.raises(ValueError, match="points of shape"):
        process.propagate(np.zeros((3, 2)), 0.01)


@pytest.mark.parametrize("tyre_model", TYRE_MODELS)
@pytest.mark.parametrize("sensor", SENSORS)
def test_measurement_jacobians_match_finite_differences(sensor: str, tyre_model: str) -> None:
    model = build_measurement_models(
        BELIEF, 0.05, 0.5, bicycle=BicycleParams.from_vehicle(BELIEF, tyre_model, ROLL))[sensor]
    for x in _random_states(20, seed=4):
        h, jacobian = model.evaluate(x)
        np.testing.assert_array_equal(model.value(x), h)
        numeric = _finite_difference(lambda s: model.evaluate(s)[0], x)
        np.testing.assert_allclose(jacobian, numeric, rtol=1e-6, atol=1e-6)


def test_gnss_velocity_model_by_hand() -> None:
    """Heading 30 deg, 20 m/s forward and 0.5 m/s to the left: east 20 cos - 0.5 sin,
    north 20 sin + 0.5 cos."""
    model = build_measurement_models(BELIEF, 0.05, 0.5)["gnss_velocity"]
    yaw = math.radians(30.0)
    h, _ = model.evaluate(_state(yaw_rad=yaw, vx_mps=20.0, vy_mps=0.5))
    np.testing.assert_allclose(h, [20.0 * math.cos(yaw) - 0.5 * math.sin(yaw),
                                   20.0 * math.sin(yaw) + 0.5 * math.cos(yaw)])


def test_wheel_speed_model_by_hand() -> None:
    """Rear-wheel drive: the free-rolling front wheels are fused, the driven rear ignored.

    Straight at 10 m/s turning left at 0.5 rad/s without steering (a drifting car): the
    left front wheel centre moves at 10 - 0.5 * 0.8 = 9.6 m/s forward.
    """
    radius = BELIEF.wheel_radius_m
    model = build_measurement_models(BELIEF, 0.05, 0.5)["wheel_speed"]
    assert model.channels == ("front_left_radps", "front_right_radps")
    assert model.ignored_channels == ("rear_left_radps", "rear_right_radps")
    h, _ = model.evaluate(_state(vx_mps=10.0, yaw_rate_radps=0.5))
    np.testing.assert_allclose(h, [9.6 / radius, 10.4 / radius])
    # A tyre that rolls on a 1 % smaller radius spins 1 % faster.
    h, _ = model.evaluate(_state(vx_mps=10.0, yaw_rate_radps=0.5, rolling_radius_scale=0.99))
    np.testing.assert_allclose(h, [9.6 / (0.99 * radius), 10.4 / (0.99 * radius)])
    # An effective track 10 % wider than believed: the turn's difference grows by 10 %.
    h, _ = model.evaluate(_state(vx_mps=10.0, yaw_rate_radps=0.5, wheel_track_scale=1.1))
    np.testing.assert_allclose(h, [9.56 / radius, 10.44 / radius])
    # Steered 0.1 rad: each wheel spins at its centre velocity along its Ackermann plane.
    x = _state(vx_mps=10.0, vy_mps=0.2, yaw_rate_radps=0.3, steer_rad=0.1)
    left, right = ackermann_angles(0.1, BELIEF.wheelbase_m, BELIEF.track_m)
    sideways = 0.2 + 0.3 * BELIEF.cog_front_m
    expected = [
        ((10.0 - 0.3 * 0.8) * math.cos(left) + sideways * math.sin(left)) / radius,
        ((10.0 + 0.3 * 0.8) * math.cos(right) + sideways * math.sin(right)) / radius,
    ]
    np.testing.assert_allclose(model.evaluate(x)[0], expected, rtol=1e-12)


def test_wheel_speed_model_uses_each_axles_believed_track() -> None:
    """All-wheel drive (all four fused), front track 1.5 m, rear 1.7 m: turning at 0.5 rad/s
    at 10 m/s unsteered, the wheels' centres move at 10 -+ 0.5 * 0.75 m/s at the front and
    10 -+ 0.5 * 0.85 m/s at the rear."""
    belief = VehicleParams(drive="awd", track_front_m=1.5, track_rear_m=1.7)
    radius = belief.wheel_radius_m
    model = build_measurement_models(belief, 0.05, 0.5)["wheel_speed"]
    h, _ = model.evaluate(_state(vx_mps=10.0, yaw_rate_radps=0.5))
    np.testing.assert_allclose(
        h, np.array([9.625, 10.375, 9.575, 10.425]) / radius, rtol=1e-12)


@pytest.mark.parametrize(("drive", "fused"), [
    ("fwd", ("rear_left_radps", "rear_right_radps")),
    ("awd", ("front_left_radps", "front_right_radps", "rear_left_radps", "rear_right_radps")),
])
def test_wheels_fused_follow_the_drive(drive: str, fused: tuple[str, ...]) -> None:
    model = build_measurement_models(VehicleParams(drive=drive), 0.05, 0.5)["wheel_speed"]
    assert model.channels == fused


def test_imu_model_by_hand() -> None:
    """Gyro: yaw rate plus bias. Accelerometer: ax plus bias; ay = (F_f + F_r) / m + d.

    Linear tyres at 20 m/s, vy = -0.1, r = 0.25, delta = 0.05: alpha_f = 0.05 - (-0.1 +
    0.3) / 20 = 0.04, alpha_r = -(-0.1 - 0.4) / 20 = 0.025.
    """
    model = build_measurement_models(
        BELIEF, 0.05, 0.5, bicycle=BicycleParams.from_vehicle(BELIEF, "linear"))["imu"]
    x = _state(vx_mps=20.0, vy_mps=-0.1, yaw_rate_radps=0.25, steer_rad=0.05, ax_mps2=-1.0,
               gyro_bias_radps=0.002, ax_bias_mps2=0.03, lateral_accel_residual_mps2=0.2)
    ay = (72550.0 * 0.04 + 79580.0 * 0.025) / BELIEF.mass_kg + 0.2
    np.testing.assert_allclose(model.evaluate(x)[0], [0.252, -0.97, ay], rtol=1e-12)


def test_measurement_channel_selection() -> None:
    model = build_measurement_models(BELIEF, 0.05, 0.5)["wheel_speed"]
    names = ("front_left_radps", "front_right_radps", "rear_left_radps", "rear_right_radps")
    assert model.select(names) == ((0, 1), (0, 1))
    assert model.select(("front_right_radps",)) == ((1,), (0,))
    with pytest.raises(ValueError, match="spare_radps"):
        model.select(("spare_radps",))


@pytest.mark.parametrize(
    ("angle", "expected"),
    [
        (0.0, 0.0),
        (math.pi, math.pi),
        (-math.pi, math.pi),
        (3 * math.pi, math.pi),
        (2 * math.pi + 0.1, 0.1),
        (-2 * math.pi - 0.1, -0.1),
        (math.pi + 0.2, -math.pi + 0.2),
        (np.nextafter(math.pi, 4.0), -math.pi),
        (np.nextafter(-math.pi, -4.0), math.pi),
        (-math.pi + 1e-6, -math.pi + 1e-6),
    ],
)
def test_wrap_angle(angle: float, expected: float) -> None:
    """Equal to ``expected`` modulo 2 pi (to rounding), and always in (-pi, pi]."""
    wrapped = wrap_angle(angle)
    assert -math.pi < wrapped <= math.pi
    assert math.remainder(wrapped - expected, 2 * math.pi) == pytest.approx(0.0, abs=1e-12)
