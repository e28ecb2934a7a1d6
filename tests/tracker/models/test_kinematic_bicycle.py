"""The CasADi kinematic bicycle against numbers a reader can check by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosim.core.exceptions import ConfigError
from cosim.core.vehicle_params import VehicleParams
from tests.tracker.closed_loop import CarState, derivative
from tracker.models.kinematic_bicycle import (
    INPUT,
    INPUT_NAMES,
    STATE,
    STATE_NAMES,
    continuous_function,
    discrete_function,
    predict_function,
    slip_angle,
)

PARAMS = VehicleParams()


def _state(x_m: float = 0.0, y_m: float = 0.0, yaw_rad: float = 0.0,
           speed_mps: float = 0.0) -> np.ndarray:
    state = np.zeros(len(STATE_NAMES))
    state[STATE["x_m"]] = x_m
    state[STATE["y_m"]] = y_m
    state[STATE["yaw_rad"]] = yaw_rad
    state[STATE["vx_mps"]] = speed_mps
    return state


def _inputs(accel_mps2: float = 0.0, steer_rad: float = 0.0) -> np.ndarray:
    inputs = np.zeros(len(INPUT_NAMES))
    inputs[INPUT["accel_mps2"]] = accel_mps2
    inputs[INPUT["steer_rad"]] = steer_rad
    return inputs


def _simulate(state: np.ndarray, inputs: np.ndarray, duration_s: float,
              dt_s: float = 0.05) -> np.ndarray:
    step = discrete_function(PARAMS, dt_s)
    for _ in range(int(round(duration_s / dt_s))):
        state = np.asarray(step(state, inputs), dtype=float).ravel()
    return state


def test_names_and_index_maps_agree() -> None:
    assert STATE_NAMES == ("x_m", "y_m", "yaw_rad", "vx_mps")
    assert INPUT_NAMES == ("accel_mps2", "steer_rad")
    assert [STATE[n] for n in STATE_NAMES] == list(range(len(STATE_NAMES)))
    assert [INPUT[n] for n in INPUT_NAMES] == list(range(len(INPUT_NAMES)))


def test_straight_line_20_mps_for_2_s_is_40_m() -> None:
    end = _simulate(_state(speed_mps=20.0), _inputs(), 2.0)
    assert end[STATE["x_m"]] == pytest.approx(40.0, abs=1e-9)
    assert end[STATE["y_m"]] == pytest.approx(0.0, abs=1e-12)
    assert end[STATE["vx_mps"]] == pytest.approx(20.0)


def test_straight_line_heading_north() -> None:
    end = _simulate(_state(yaw_rad=math.pi / 2, speed_mps=10.0), _inputs(), 3.0)
    assert end[STATE["x_m"]] == pytest.approx(0.0, abs=1e-9)
    assert end[STATE["y_m"]] == pytest.approx(30.0, abs=1e-9)


def test_constant_acceleration() -> None:
    # 15 m/s + 3 m/s^2 for 1 s: 18 m/s, 15 + 1.5 = 16.5 m.
    end = _simulate(_state(speed_mps=15.0), _inputs(accel_mps2=3.0), 1.0)
    assert end[STATE["vx_mps"]] == pytest.approx(18.0)
    assert end[STATE["x_m"]] == pytest.approx(16.5, abs=1e-9)


def test_steady_turn_yaw_rate() -> None:
    # yaw' = v cos(beta) tan(delta) / L; at small angles about v delta / L.
    speed, steer = 10.0, 0.05
    wheelbase = PARAMS.cog_front_m + PARAMS.cog_rear_m
    beta = math.atan(PARAMS.cog_rear_m / wheelbase * math.tan(steer))
    expected = speed * math.cos(beta) * math.tan(steer) / wheelbase
    assert expected == pytest.approx(speed * steer / wheelbase, rel=2e-3)

    f = continuous_function(PARAMS)
    rate = np.asarray(f(_state(speed_mps=speed), _inputs(steer_rad=steer)), dtype=float).ravel()
    assert rate[STATE["yaw_rad"]] == pytest.approx(expected, rel=1e-12)

    end = _simulate(_state(speed_mps=speed), _inputs(steer_rad=steer), 2.0)
    assert end[STATE["yaw_rad"]] == pytest.approx(2.0 * expected, rel=1e-9)


def test_steady_turn_is_a_circle_of_the_kinematic_radius() -> None:
    # The CoG runs on a circle of radius L / (cos(beta) tan(delta)); after a quarter turn
    # its position is fixed by geometry alone.
    speed, steer = 20.0, 0.035
    wheelbase = PARAMS.wheelbase_m
    beta = float(slip_angle(steer, PARAMS))
    radius = wheelbase / (math.cos(beta) * math.tan(steer))
    yaw_rate = speed / radius
    duration = 0.5 * math.pi / yaw_rate
    dt = duration / 200
    end = _simulate(_state(speed_mps=speed), _inputs(steer_rad=steer), duration, dt)
    course0, course1 = beta, beta + 0.5 * math.pi
    centre = np.array([-radius * math.sin(course0), radius * math.cos(course0)])
    expected = centre + radius * np.array([math.sin(course1), -math.cos(course1)])
    assert end[STATE["x_m"]] == pytest.approx(expected[0], abs=1e-6)
    assert end[STATE["y_m"]] == pytest.approx(expected[1], abs=1e-6)


def test_slip_angle_positive_left_and_small() -> None:
    assert float(slip_angle(0.1, PARAMS)) == pytest.approx(
        math.atan(1.6 / 2.8 * math.tan(0.1)))
    assert float(slip_angle(-0.1, PARAMS)) == pytest.approx(-float(slip_angle(0.1, PARAMS)))


def test_casadi_model_matches_plain_numpy() -> None:
    f = continuous_function(PARAMS)
    rng = np.random.default_rng(3)
    for _ in range(20):
        x, y, yaw, v = rng.uniform([-50, -50, -np.pi, 0], [50, 50, np.pi, 30])
        accel, steer = rng.uniform([-3, -0.4], [3, 0.4])
        plain = derivative(CarState(x, y, yaw, v), accel, steer, PARAMS)
        symbolic = np.asarray(f(_state(x, y, yaw, v), _inputs(accel, steer)), dtype=float)
        symbolic = symbolic.ravel()
        assert symbolic[STATE["x_m"]] == pytest.approx(plain.x_m, rel=1e-12, abs=1e-12)
        assert symbolic[STATE["y_m"]] == pytest.approx(plain.y_m, rel=1e-12, abs=1e-12)
        assert symbolic[STATE["yaw_rad"]] == pytest.approx(plain.yaw_rad, rel=1e-12, abs=1e-12)
        assert symbolic[STATE["vx_mps"]] == pytest.approx(plain.speed_mps, rel=1e-12)


def test_predict_over_zero_and_positive_duration() -> None:
    predict = predict_function(PARAMS)
    state = _state(speed_mps=20.0)
    same = np.asarray(predict(state, _inputs(), 0.0), dtype=float).ravel()
    assert same == pytest.approx(state)
    later = np.asarray(predict(state, _inputs(), 0.1), dtype=float).ravel()
    assert later[STATE["x_m"]] == pytest.approx(2.0)


def test_bad_step_is_refused() -> None:
    with pytest.raises(ConfigError, match="dt_s"):
        discrete_function(PARAMS, 0.0)
    with pytest.raises(ConfigError, match="substeps"):
        discrete_function(PARAMS, 0.05, substeps=0)


def test_understeer_variant_turns_at_the_linear_tyres_steady_state() -> None:
    """(U1)-(U2) against the steady state of the linear-tyre dynamic bicycle, computed here
    from its 2x2 lateral equations (Rajamani 2012, sec. 2.3) with plain numpy."""
    params = VehicleParams()
    m, iz = params.mass_kg, params.yaw_inertia_kgm2
    lf, lr = params.cog_front_m, params.cog_rear_m
    cf, cr = params.cornering_stiffness_front_npr, params.cornering_stiffness_rear_npr
    speed, steer = 20.0, 0.03
    # v_y' = a11 v_y + a12 r + b1 delta, r' = a21 v_y + a22 r + b2 delta = 0 in the steady turn.
    a = np.array([
        [-(cf + cr) / (m * speed), (lr * cr - lf * cf) / (m * speed) - speed],
        [(lr * cr - lf * cf) / (iz * speed), -(lf**2 * cf + lr**2 * cr) / (iz * speed)],
    ])
    b = np.array([cf / m, lf * cf / iz])
    vy, r = np.linalg.solve(a, -b * steer)
    state = np.array([0.0, 0.0, 0.3, speed])
    rate = np.asarray(continuous_function(params, understeer=True)(state, [0.0, steer])).ravel()
    assert rate[STATE["yaw_rad"]] == pytest.approx(r, rel=2e-3)  # tan(delta) vs delta
    course = math.atan2(rate[STATE["y_m"]], rate[STATE["x_m"]]) - 0.3
    assert course == pytest.approx(math.atan2(vy, speed), rel=5e-3)
    # The understeering car turns less than the kinematic one.
    kinematic = np.asarray(continuous_function(params)(state, [0.0, steer])).ravel()
    assert rate[STATE["yaw_rad"]] < 0.9 * kinematic[STATE["yaw_rad"]]

