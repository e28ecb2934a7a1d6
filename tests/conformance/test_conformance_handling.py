"""Conformance in corners: understeer in the linear range, saturation at the grip limit.

Steady-state yaw-rate gain of a car with understeer gradient K (Gillespie, "Fundamentals
of Vehicle Dynamics", 1992, eq. 6.15; Rajamani, "Vehicle Dynamics and Control", 2012,
§3.5)::

    r / delta = (v / L) / (1 + K v^2 / (g L)),   K in rad per g

so ``K = (v / (L gain) - 1) g L / v^2``. Numbers a reader can check: the kinematic gain
v / L is 3.57, 7.14 and 10.71 1/s at 10, 20 and 30 m/s; with K = 2 deg/g = 0.0349 rad/g
it falls to 3.16, 4.72 and 5.00 1/s. A passenger sedan lies at about 1.5-3 deg/g; the
MathWorks lane-keeping example's C_f = 19000, C_r = 33000 N/rad would give 15 deg/g
(models/README.md).

At the limit, a car whose tyres all peak at mu F_z corners at about mu g: 9.8 m/s^2 on a
dry road (mu = 1), 4.9 m/s^2 on a wet one (mu = 0.5).
"""

from __future__ import annotations

import math

import pytest

from cosim.core.records import VehicleState
from cosim.core.vehicle_params import PlantConfig
from tests.conformance.driving import (
    GRAVITY_MPS2,
    WHEELBASE_M,
    drive,
    low_pass,
    plant_at,
    speed_loop,
)

pytestmark = pytest.mark.conformance

SPEEDS_MPS = (10.0, 20.0, 30.0)
TARGET_LATERAL_MPS2 = 2.0
"""Steady turns at about 0.2 g, inside the tyres' linear range."""

STEADY_AFTER_S = 4.0
MEASURE_S = 1.0


def understeer_gradient_degpg(speed_mps: float, gain_per_s: float) -> float:
    """K from the measured yaw-rate gain (module docstring), in deg/g."""
    kinematic = speed_mps / WHEELBASE_M
    return math.degrees((kinematic / gain_per_s - 1.0) * GRAVITY_MPS2 * WHEELBASE_M
                        / speed_mps**2)


def steady_gains(config: PlantConfig) -> dict[float, float]:
    """Steady yaw-rate gain r / delta [1/s] at each speed, steering for about 0.2 g."""
    gains = {}
    for speed in SPEEDS_MPS:
        # delta = a_y (L / v^2 + K) with K = 2 deg/g, so each turn is near 0.2 g.
        steer = TARGET_LATERAL_MPS2 * (WHEELBASE_M / speed**2 + math.radians(2.0)
                                       / GRAVITY_MPS2)
        states = drive(plant_at(speed, config), STEADY_AFTER_S + MEASURE_S,
                       speed_loop(config, speed, lambda _t, s=steer: s))
        window = [s for s in states if s.t_s > STEADY_AFTER_S]
        yaw_rate = sum(s.yaw_rate_radps for s in window) / len(window)
        assert all(s.vx_mps == pytest.approx(speed, rel=0.01) for s in window)
        gains[speed] = yaw_rate / steer
    return gains


@pytest.fixture(scope="module")
def pacejka_gains() -> dict[float, float]:
    return steady_gains(PlantConfig())


@pytest.mark.parametrize("speed_mps", SPEEDS_MPS)
def test_yaw_rate_gain_is_below_the_kinematic_one(pacejka_gains: dict[float, float],
                                                  speed_mps: float) -> None:
    gain = pacejka_gains[speed_mps]
    assert gain < speed_mps / WHEELBASE_M
    assert 0.5 <= understeer_gradient_degpg(speed_mps, gain) <= 4.0


def test_understeer_gradient_is_that_of_a_sedan_at_every_speed(
        pacejka_gains: dict[float, float]) -> None:
    gradients = [understeer_gradient_degpg(v, g) for v, g in pacejka_gains.items()]
    # The calibrated default: 1.5-3 deg/g, the same at 10, 20 and 30 m/s (a linear car).
    assert all(1.5 <= k <= 3.0 for k in gradients)
    assert max(gradients) - min(gradients) < 0.3


def test_contact_tyres_are_neutral_for_comparison() -> None:
    # MuJoCo's contact friction has no cornering stiffness: the car steers kinematically.
    gains = steady_gains(PlantConfig(tyre_model="contact"))
    assert all(abs(understeer_gradient_degpg(v, g)) < 0.3 for v, g in gains.items())


DEPARTURE_SIDESLIP_RAD = 0.2
"""Sideslip at the CoG beyond which the car has left the quasi-steady corner (it spins)."""


@pytest.mark.parametrize(
    ("friction", "steer_rate_radps"), [(1.0, 0.02), (0.5, 0.01)]
)
def test_lateral_acceleration_saturates_near_mu_g(friction: float,
                                                  steer_rate_radps: float) -> None:
    # Ramp steer at 20 m/s, speed held: a_y (low-passed over 0.1 s) grows with the steer
    # until the tyres saturate, and the car departs (the rear-driven car, its rear tyres
    # also driving against the cornering drag, spins) before the ramp ends at 0.3 rad. The
    # highest a_y reached is within 15 % of mu g.
    config = PlantConfig(tyre_friction=friction)

    def sideslip_rad(state: VehicleState) -> float:
        return math.atan2(state.vy_mps, max(state.vx_mps, 0.1))

    ramp_s = 0.3 / steer_rate_radps
    states = drive(
        plant_at(20.0, config),
        ramp_s,
        speed_loop(config, 20.0, lambda t: steer_rate_radps * t, gain_per_s=5.0),
        stop=lambda s: abs(sideslip_rad(s)) > DEPARTURE_SIDESLIP_RAD,
    )
    lateral = low_pass([s.ay_mps2 for s in states], time_constant_s=0.1)
    assert states[-1].t_s < 0.8 * ramp_s  # saturated: more steer no longer holds the turn
    assert max(lateral) == pytest.approx(friction * GRAVITY_MPS2, rel=0.15)
