"""The steered dynamic bicycle with tyres that saturate at the friction force, (D3') of
:mod:`tracker.models.dynamic_bicycle`: the linear bicycle where the tyres barely slip, never
more lateral acceleration than ``mu g`` however hard it is steered."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from cosim.core.exceptions import ConfigError
from cosim.core.physical_constants import GRAVITY_MPS2
from cosim.core.vehicle_params import VehicleParams
from tests.named_vectors import named_vector
from tracker.models.dynamic_bicycle import steady_understeer_rad
from tracker.models.steered_dynamic_bicycle import (
    BELIEF_NAMES,
    INPUT,
    STATE,
    SteeredBicycleParams,
    belief_discrete_function,
    belief_vector,
    continuous_function,
    discrete_function,
)

WET = VehicleParams(tyre_friction=0.6)
LINEAR = SteeredBicycleParams.from_vehicle(WET)
SATURATING = SteeredBicycleParams.from_vehicle(WET, saturating=True)
SPEED_MPS = 20.0


def _steady_turn(params: SteeredBicycleParams, steer_rad: float) -> np.ndarray:
    """The state after 6 s at ``SPEED_MPS`` with ``steer_rad`` held (no acceleration), from
    straight running with the wheel at the angle already."""
    step = discrete_function(params, 0.05)
    state = named_vector(STATE, vx_mps=SPEED_MPS, road_wheel_angle_rad=steer_rad)
    inputs = named_vector(INPUT, steer_rad=steer_rad)
    for _ in range(120):
        state = np.asarray(step(state, inputs), dtype=float).ravel()
    return state


def _lateral_accel_mps2(params: SteeredBicycleParams, state: np.ndarray,
                        steer_rad: float) -> float:
    """``vy' + vx r``: the tyres' lateral force over the mass, at ``state``."""
    inputs = named_vector(INPUT, steer_rad=steer_rad)
    rate = np.asarray(continuous_function(params)(state, inputs), dtype=float).ravel()
    return float(rate[STATE["vy_mps"]]
                 + state[STATE["vx_mps"]] * state[STATE["yaw_rate_radps"]])


def test_where_the_tyres_barely_slip_the_model_is_the_linear_one() -> None:
    """A 0.18 m/s^2 turn (2 mrad of steering at 20 m/s): the tyres use 3 % of their grip,
    where ``tanh(x) / x`` is 0.9997; the yaw rates agree to 0.05 %."""
    linear, saturating = _steady_turn(LINEAR, 0.002), _steady_turn(SATURATING, 0.002)
    r = STATE["yaw_rate_radps"]
    assert _lateral_accel_mps2(LINEAR, linear, 0.002) == pytest.approx(0.183, abs=0.001)
    assert saturating[r] == pytest.approx(linear[r], rel=5e-4)


def test_steered_beyond_the_grip_the_turn_stays_within_mu_g() -> None:
    """0.15 rad at 20 m/s asks the linear tyres for more than twice the wet road's grip
    (they give it: 13.7 m/s^2); the saturating tyres give the car at most ``mu g``
    (5.9 m/s^2), and more than 70 % of it (a tyre at its limit still pulls; with both
    axles there the bicycle slides outward, as a car beyond its grip does)."""
    limit = WET.tyre_friction * GRAVITY_MPS2
    linear = _lateral_accel_mps2(LINEAR, _steady_turn(LINEAR, 0.15), 0.15)
    saturating = _lateral_accel_mps2(SATURATING, _steady_turn(SATURATING, 0.15), 0.15)
    assert linear > 2.0 * limit
    assert 0.7 * limit < saturating <= limit * (1.0 + 1e-9)


def test_the_friction_is_a_number_of_the_belief_not_of_the_code() -> None:
    """One function of the belief serves every friction: at the belief vector of a friction
    it steps as the function built for that friction (one compiled NLP for a sweep over
    the road's friction)."""
    shape = SATURATING
    step = belief_discrete_function(shape, 0.05)
    state = named_vector(STATE, vx_mps=SPEED_MPS, yaw_rate_radps=0.2, vy_mps=-0.3,
                         road_wheel_angle_rad=0.05)
    inputs = named_vector(INPUT, steer_rad=0.08)
    stepped = {}
    for friction in (0.4, 0.9):
        numbers = dataclasses.replace(shape, tyre_friction=friction)
        by_belief = np.asarray(step(state, inputs, belief_vector(numbers))).ravel()
        built = np.asarray(discrete_function(numbers, 0.05)(state, inputs)).ravel()
        np.testing.assert_allclose(by_belief, built, rtol=1e-12, atol=1e-12)
        stepped[friction] = by_belief
    assert "tyre_friction" in BELIEF_NAMES
    assert not np.allclose(stepped[0.4], stepped[0.9])


def test_a_friction_that_is_no_number_is_refused() -> None:
    with pytest.raises(ConfigError, match="tyre_friction = 0.0"):
        dataclasses.replace(SATURATING, tyre_friction=0.0)


@pytest.mark.parametrize(("params", "grip_mps2"), [
    (LINEAR, None), (SATURATING, WET.tyre_friction * GRAVITY_MPS2)])
def test_the_steady_turns_steering_is_what_the_model_needs(
        params: SteeredBicycleParams, grip_mps2: float | None) -> None:
    """(S4) (and (S1) for the linear tyres), the steering the curvature feed-forward asks for
    beyond the kinematic ``atan(L kappa)``: the model held at 0.04 rad settles into a turn
    (3.5 m/s^2, 0.59 of the wet road's grip, with saturating tyres) whose curvature
    ``r / vx`` and speed give back the understeer part of the 0.04 rad to 0.5 %. For the
    saturating model the linear tyres' (S1) gives 13 % too little of it."""
    state = _steady_turn(params, 0.04)
    speed = np.array([state[STATE["vx_mps"]]])
    curvature = np.array([state[STATE["yaw_rate_radps"]]]) / speed
    needed = 0.04 - math.atan(params.bicycle.wheelbase_m * float(curvature[0]))
    gradient = params.bicycle.understeer_gradient_radpmps2
    steady = float(steady_understeer_rad(gradient, speed, curvature, grip_mps2)[0])
    assert steady == pytest.approx(needed, rel=5e-3)
    if grip_mps2 is not None:
        assert float(steady_understeer_rad(gradient, speed, curvature)[0]) < 0.9 * needed
