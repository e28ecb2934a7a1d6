"""The EKF's process and measurement models: Jacobians, process noise, hand-checkable motion."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg

from cosim.vehicle_params import VehicleParams
from estimation.config import EstimatorConfig
from estimation.models import (
    STATE_NAMES,
    ProcessModel,
    ProcessNoise,
    build_measurement_models,
    state_index,
    wrap_angle,
)

CONFIG = EstimatorConfig()
NOISE = ProcessNoise(
    position_psd_m2ps=CONFIG.position_psd_m2ps,
    yaw_psd_rad2ps=CONFIG.yaw_psd_rad2ps,
    lateral_accel_psd_m2ps3=CONFIG.lateral_accel_psd_m2ps3,
    yaw_accel_psd_rad2ps3=CONFIG.yaw_accel_psd_rad2ps3,
    jerk_psd_m2ps5=CONFIG.jerk_psd_m2ps5,
    rolling_radius_scale_psd_1ps=CONFIG.rolling_radius_scale_psd_1ps,
)


@pytest.fixture(scope="module")
def process() -> ProcessModel:
    return ProcessModel(NOISE, CONFIG.lateral_velocity_time_constant_s)


def _state(**values: float) -> np.ndarray:
    x = np.zeros(len(STATE_NAMES))
    x[state_index("rolling_radius_scale")] = 1.0
    for name, value in values.items():
        x[state_index(name)] = value
    return x


def _random_states(count: int, seed: int) -> list[np.ndarray]:
    """States over the whole envelope, including yaw near +-pi and zero yaw rate."""
    rng = np.random.default_rng(seed)
    states = [
        _state(x_m=3.0, y_m=-2.0, yaw_rad=math.pi - 1e-3, vx_mps=20.0, yaw_rate_radps=0.0),
        _state(yaw_rad=-math.pi + 1e-3, vx_mps=0.0, vy_mps=0.3, yaw_rate_radps=-0.4),
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
                rolling_radius_scale=rng.uniform(0.95, 1.05),
            )
        )
    return states


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
    assert set(STATE_NAMES) >= {"x_m", "y_m", "yaw_rad", "vx_mps", "yaw_rate_radps", "ax_mps2"}
    with pytest.raises(KeyError, match="unknown state"):
        state_index("speed")


@pytest.mark.parametrize("dt_s", [0.001, 0.01, 0.02])
def test_process_jacobian_matches_finite_differences(process: ProcessModel, dt_s: float) -> None:
    for x in _random_states(20, seed=1):
        _, transition, _ = process.step(x, dt_s)
        numeric = _finite_difference(lambda s: process.step(s, dt_s)[0].reshape(-1), x)
        np.testing.assert_allclose(transition, numeric, rtol=1e-6, atol=1e-8)


def test_continuous_jacobian_matches_finite_differences(process: ProcessModel) -> None:
    for x in _random_states(20, seed=2):
        _, a = process.derivative(x)
        numeric = _finite_difference(lambda s: process.derivative(s)[0], x)
        np.testing.assert_allclose(a, numeric, rtol=1e-6, atol=1e-8)


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
    w = NOISE.diagonal()
    for x in _random_states(10, seed=3):
        _, _, q = process.step(x, dt_s)
        _, a = process.derivative(x)
        reference = _van_loan(a, w, dt_s)
        scale = np.sqrt(np.outer(np.diag(reference), np.diag(reference))) + 1e-300
        np.testing.assert_allclose(q / scale, reference / scale, atol=1e-9)
        np.testing.assert_array_equal(q, q.T)
        assert np.linalg.eigvalsh(q).min() > -1e-15


def test_process_noise_grows_with_the_interval_as_expected(process: ProcessModel) -> None:
    """Jerk noise alone: variance of ax grows as q t, of vx as q t^3 / 3 (straight line)."""
    x = _state(vx_mps=10.0)
    _, _, q = process.step(x, 0.02)
    ax, vx = state_index("ax_mps2"), state_index("vx_mps")
    assert q[ax, ax] == pytest.approx(CONFIG.jerk_psd_m2ps5 * 0.02, rel=1e-12)
    assert q[vx, vx] == pytest.approx(CONFIG.jerk_psd_m2ps5 * 0.02**3 / 3, rel=1e-12)


def test_straight_line_by_hand(process: ProcessModel) -> None:
    """20 m/s for 2 s heading north-east -> 40 m along the diagonal."""
    x = _state(yaw_rad=math.pi / 4, vx_mps=20.0).reshape(-1, 1)
    for _ in range(200):
        x, _, _ = process.step(x, 0.01)
    assert x[state_index("x_m"), 0] == pytest.approx(40.0 / math.sqrt(2), abs=1e-9)
    assert x[state_index("y_m"), 0] == pytest.approx(40.0 / math.sqrt(2), abs=1e-9)
    assert x[state_index("vx_mps"), 0] == pytest.approx(20.0, abs=1e-12)


def test_ctra_closed_form(process: ProcessModel) -> None:
    """Turn and accelerate for 3 s; compare with the closed-form CTRA solution."""
    yaw0, v0, r, a, t = 0.3, 12.0, 0.4, 1.5, 3.0
    x = _state(x_m=1.0, y_m=2.0, yaw_rad=yaw0, vx_mps=v0, yaw_rate_radps=r, ax_mps2=a)
    x = x.reshape(-1, 1)
    for _ in range(300):
        x, _, _ = process.step(x, 0.01)
    yaw, v = yaw0 + r * t, v0 + a * t
    x_expected = 1.0 + (v * r * math.sin(yaw) + a * math.cos(yaw)) / r**2
    x_expected -= (v0 * r * math.sin(yaw0) + a * math.cos(yaw0)) / r**2
    y_expected = 2.0 + (-v * r * math.cos(yaw) + a * math.sin(yaw)) / r**2
    y_expected -= (-v0 * r * math.cos(yaw0) + a * math.sin(yaw0)) / r**2
    assert x[state_index("x_m"), 0] == pytest.approx(x_expected, abs=1e-8)
    assert x[state_index("y_m"), 0] == pytest.approx(y_expected, abs=1e-8)
    assert x[state_index("yaw_rad"), 0] == pytest.approx(yaw, abs=1e-12)
    assert x[state_index("vx_mps"), 0] == pytest.approx(v, abs=1e-12)


def test_sideslip_moves_the_car_sideways(process: ProcessModel) -> None:
    """Heading east with vy = 1 m/s to the left: the CoG drifts north (before vy decays)."""
    x = _state(vx_mps=10.0, vy_mps=1.0).reshape(-1, 1)
    x_next, _, _ = process.step(x, 0.01)
    assert x_next[state_index("y_m"), 0] == pytest.approx(0.01 * 1.0, rel=1e-2)
    tau = CONFIG.lateral_velocity_time_constant_s
    assert x_next[state_index("vy_mps"), 0] == pytest.approx(math.exp(-0.01 / tau), rel=1e-9)


def test_step_refuses_long_substeps(process: ProcessModel) -> None:
    with pytest.raises(ValueError, match="sub-step"):
        process.step(_state(), 0.05)


@pytest.mark.parametrize("sensor", ["gnss", "imu", "wheel_speed", "heading"])
def test_measurement_jacobians_match_finite_differences(sensor: str) -> None:
    model = build_measurement_models(VehicleParams(), 0.05, 0.5)[sensor]
    for x in _random_states(20, seed=4):
        _, jacobian = model.evaluate(x)
        numeric = _finite_difference(lambda s: model.evaluate(s)[0], x)
        np.testing.assert_allclose(jacobian, numeric, rtol=1e-6, atol=1e-8)


def test_wheel_speed_model_by_hand() -> None:
    """Turning left at 0.5 rad/s and 10 m/s, track 1.6 m: the left wheel is slower."""
    belief = VehicleParams()
    model = build_measurement_models(belief, 0.05, 0.5)["wheel_speed"]
    h, _ = model.evaluate(_state(vx_mps=10.0, yaw_rate_radps=0.5))
    assert model.channels == ("rear_left_radps", "rear_right_radps")
    radius = belief.wheel_radius_m
    np.testing.assert_allclose(h, [(10.0 - 0.4) / radius, (10.0 + 0.4) / radius])
    # A tyre that rolls on a 1 % smaller radius spins 1 % faster.
    h, _ = model.evaluate(_state(vx_mps=10.0, yaw_rate_radps=0.5, rolling_radius_scale=0.99))
    np.testing.assert_allclose(h, [9.6 / (0.99 * radius), 10.4 / (0.99 * radius)])


def test_lateral_acceleration_model_by_hand() -> None:
    model = build_measurement_models(VehicleParams(), 0.05, 0.5)["imu"]
    h, _ = model.evaluate(_state(vx_mps=20.0, yaw_rate_radps=0.25, ax_mps2=-1.0))
    np.testing.assert_allclose(h, [0.25, -1.0, 5.0])


def test_measurement_channel_selection() -> None:
    model = build_measurement_models(VehicleParams(), 0.05, 0.5)["wheel_speed"]
    names = ("front_left_radps", "front_right_radps", "rear_left_radps", "rear_right_radps")
    assert model.select(names) == ((0, 1), (2, 3))
    assert model.select(("rear_right_radps",)) == ((1,), (0,))
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
