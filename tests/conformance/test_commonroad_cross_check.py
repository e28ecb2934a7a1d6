"""Cross-check of the plant against an independent vehicle model: CommonRoad's single-track
model (``commonroad-vehicle-models``, Althoff, Koschi and Manzinger, "CommonRoad: Composable
benchmarks for motion planning on roads", IEEE Intelligent Vehicles Symposium 2017; the
models' documentation "CommonRoad: Vehicle Models", 2020).

The plant is configured from CommonRoad's parameter set 2 (a BMW 320i): mass, yaw inertia,
CoG position and height, mean track, wheel radius and spin inertia, friction ``p_dy1``. Its
single-track model gives each axle the cornering stiffness ``C_S F_z`` with ``C_S =
-p_ky1 / p_dy1`` per unit of friction and load (21.9 per rad for both axles, so the model is
neutral-steer: ``r / delta = v / L``). The plant's Magic Formula tyre is set to the same
stiffness at the static axle loads: nominal load the static front wheel load, ``p_Ky2 = 9``
(so the stiffness is nearly linear in the load, as the single-track model's), ``p_Ky1`` for
21.9 per rad at the front and the rear axle's scale for the same at the rear (the front
steering-compliance scale set to 1: the single-track model has none).

What differs is what the plant adds: suspension, roll and lateral load transfer, wheels
that spin, tyres that relax, a steering servo. Steady turns at about 0.2 g (in the tyres'
linear range) at 10, 20 and 30 m/s. Measured: the plant's yaw-rate gain is 0.5 / 2.5 / 8.2 %
below the single-track model's: a slight understeer the single-track model has not,
growing with speed, 0.07 / 0.09 / 0.14 deg/g as an understeer gradient
``K = (v / (L r/delta) - 1) L / v^2`` (its source is not pinned down; the lower ``p_Ky2``
of 5 against 9 changes it by less than 0.01 deg/g, so it is not the tyres' load
sensitivity). The test bounds that gradient at 0.2 deg/g at each speed (1.5 times the
worst, rounded): a 10 % error in one axle's cornering stiffness alone would add 0.26 deg/g,
and the default sedan has 2.2 deg/g.

CommonRoad's multi-body model (``vehicle_dynamics_mb``: sprung mass with roll and pitch,
suspension, its own Magic Formula tyres) is the second reference, at the same turns (no
wheel lifts at 0.2 g, where the model would be invalid), and for a 20 m/s step steer.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from vehiclemodels.init_mb import init_mb
from vehiclemodels.parameters_vehicle2 import parameters_vehicle2
from vehiclemodels.vehicle_dynamics_mb import vehicle_dynamics_mb
from vehiclemodels.vehicle_dynamics_st import vehicle_dynamics_st

from cosim.vehicle_params import PlantConfig
from tests.conformance.driving import drive, plant_at, speed_loop

pytestmark = [pytest.mark.conformance]

G = 9.81
SPEEDS_MPS = (10.0, 20.0, 30.0)
LATERAL_MPS2 = 2.0
STEADY_AFTER_S = 4.0
MEASURE_S = 1.0
PEAK_LOAD_RATIO = 9.0
"""p_Ky2 of the plant's tyre here: the cornering stiffness nearly linear in the load."""

BMW = parameters_vehicle2()


def bmw_plant() -> PlantConfig:
    """The plant with CommonRoad's BMW 320i parameters and matching tyre stiffness."""
    wheelbase = BMW.a + BMW.b
    per_load_prad = -BMW.tire.p_ky1 / BMW.tire.p_dy1 * BMW.tire.p_dy1  # C_S mu
    front_load = BMW.m * G * BMW.b / wheelbase / 2.0
    rear_load = BMW.m * G * BMW.a / wheelbase / 2.0

    def shape(load_n: float) -> float:  # K_y / (p_Ky1 F_z0) of the plant's tyre
        return math.sin(2.0 * math.atan(load_n / (PEAK_LOAD_RATIO * front_load)))

    p_ky1 = per_load_prad * front_load / (front_load * shape(front_load))
    rear_scale = per_load_prad * rear_load / (p_ky1 * front_load * shape(rear_load))
    base = PlantConfig()
    tyre = dataclasses.replace(base.tyre, nominal_load_n=front_load,
                               cornering_stiffness_max_prad=p_ky1,
                               cornering_stiffness_peak_load_ratio=PEAK_LOAD_RATIO)
    return dataclasses.replace(
        base, mass_kg=BMW.m, yaw_inertia_kgm2=BMW.I_z, cog_front_m=BMW.a, cog_rear_m=BMW.b,
        cog_height_m=BMW.h_s, track_m=0.5 * (BMW.T_f + BMW.T_r), wheel_radius_m=BMW.R_w,
        wheel_inertia_kgm2=BMW.I_y_w, tire_friction=BMW.tire.p_dy1, tyre=tyre,
        front_cornering_stiffness_scale=1.0, rear_cornering_stiffness_scale=rear_scale)


def steer_for(speed_mps: float) -> float:
    """About 0.2 g on a neutral-steer car: ``delta = a_y L / v^2``."""
    return LATERAL_MPS2 * (BMW.a + BMW.b) / speed_mps**2


def single_track_yaw_rate(speed_mps: float, steer_rad: float) -> float:
    """CommonRoad's single-track model after 6 s at constant steering and speed."""
    def rhs(_t: float, x: np.ndarray) -> list[float]:
        return vehicle_dynamics_st(list(x), [0.0, 0.0], BMW)

    # x = [x, y, steer, v, yaw, yaw rate, side slip]; inputs: steering rate, acceleration.
    start = [0.0, 0.0, steer_rad, speed_mps, 0.0, 0.0, 0.0]
    end = solve_ivp(rhs, (0.0, 6.0), start, rtol=1e-9, atol=1e-12).y[:, -1]
    assert end[3] == pytest.approx(speed_mps)
    return float(end[5])


def multi_body_gain(speed_mps: float, steer_rad: float) -> tuple[float, float]:
    """CommonRoad's multi-body model after 4 s at constant steering, no acceleration
    demand: ``(speed, yaw-rate gain)`` (its speed sags by a few cm/s: rolling losses)."""
    def rhs(_t: float, x: np.ndarray) -> list[float]:
        return vehicle_dynamics_mb(list(x), [0.0, 0.0], BMW)

    start = init_mb([0.0, 0.0, steer_rad, speed_mps, 0.0, 0.0, 0.0], BMW)
    end = solve_ivp(rhs, (0.0, 4.0), start, method="LSODA", rtol=1e-6, atol=1e-8).y[:, -1]
    return float(end[3]), float(end[5]) / steer_rad


def plant_yaw_rate(config: PlantConfig, speed_mps: float, steer_rad: float) -> float:
    states = drive(plant_at(speed_mps, config), STEADY_AFTER_S + MEASURE_S,
                   speed_loop(config, speed_mps, lambda _t: steer_rad))
    window = [s for s in states if s.t_s > STEADY_AFTER_S]
    assert all(s.vx_mps == pytest.approx(speed_mps, rel=0.01) for s in window)
    return sum(s.yaw_rate_radps for s in window) / len(window)


@pytest.fixture(scope="module")
def plant() -> PlantConfig:
    return bmw_plant()


def test_single_track_model_is_neutral_steer_with_these_parameters() -> None:
    """``C_S`` is the same for both axles, so ``K = 0`` and ``r / delta = v / L``: the
    reference below is the model itself, this only checks it is read as intended."""
    steer = steer_for(20.0)
    assert single_track_yaw_rate(20.0, steer) / steer == pytest.approx(
        20.0 / (BMW.a + BMW.b), rel=1e-4)


def understeer_gradient_degpg(speed_mps: float, gain_per_s: float) -> float:
    """``K = (v / (L r/delta) - 1) L / v^2`` in deg/g (Rajamani 2012, ch. 3)."""
    wheelbase = BMW.a + BMW.b
    gradient = (speed_mps / (wheelbase * gain_per_s) - 1.0) * wheelbase / speed_mps**2
    return math.degrees(gradient) * G


@pytest.mark.parametrize("speed_mps", SPEEDS_MPS)
def test_steady_yaw_rate_gain_matches_the_single_track_model(plant: PlantConfig,
                                                             speed_mps: float) -> None:
    steer = steer_for(speed_mps)
    reference = understeer_gradient_degpg(speed_mps,
                                          single_track_yaw_rate(speed_mps, steer) / steer)
    measured = understeer_gradient_degpg(speed_mps,
                                         plant_yaw_rate(plant, speed_mps, steer) / steer)
    assert abs(reference) < 1e-3
    assert measured == pytest.approx(reference, abs=0.2)


@pytest.mark.parametrize("speed_mps", SPEEDS_MPS)
def test_steady_yaw_rate_gain_near_the_multi_body_model(plant: PlantConfig,
                                                        speed_mps: float) -> None:
    """The multi-body model (suspension, roll, load transfer, its own Magic Formula tyres)
    is slightly oversteering here: -0.10 / -0.06 / -0.06 deg/g at 10 / 20 / 30 m/s (at the
    speed it has sagged to); the plant understeers by 0.07 / 0.09 / 0.14 deg/g, 0.17 / 0.15
    / 0.21 deg/g apart. Bound 0.35 deg/g (1.5 times the worst, rounded up): a sixth of the
    default sedan's gradient."""
    steer = steer_for(speed_mps)
    speed, gain = multi_body_gain(speed_mps, steer)
    reference = understeer_gradient_degpg(speed, gain)
    measured = understeer_gradient_degpg(speed_mps,
                                         plant_yaw_rate(plant, speed_mps, steer) / steer)
    assert measured == pytest.approx(reference, abs=0.35)


def rise_time_s(t_s: np.ndarray, yaw_rate: np.ndarray, fraction: float) -> float:
    """When ``yaw_rate`` first reaches ``fraction`` of its last value (interpolated)."""
    target = fraction * yaw_rate[-1]
    i = int(np.argmax(yaw_rate >= target))
    return float(np.interp(target, yaw_rate[i - 1:i + 1], t_s[i - 1:i + 1]))


def test_step_steer_rises_like_the_multi_body_model(plant: PlantConfig) -> None:
    """A step of the road-wheel angle at 20 m/s (to the 0.2 g turn; the plant's actuator made
    instantaneous: no lag, 10 rad/s): the yaw rate reaches 50 / 63 / 90 % of its steady
    value after 76.5 / 101.8 / 264.9 ms on the plant, 76.8 / 106.4 / 235.6 ms on the
    multi-body model (its tyres relax too; the plant's slower last 10 % is its roll and
    suspension settling). Bounds: 10 ms up to 63 %, 50 ms at 90 % (1.5 times the
    measured 29 ms, rounded up)."""
    speed, steer, step_at_s = 20.0, steer_for(20.0), 0.5
    config = dataclasses.replace(plant, steer_time_constant_s=0.0, max_steer_rate_radps=10.0)
    states = drive(plant_at(speed, config), step_at_s + 2.5,
                   speed_loop(config, speed, lambda t: steer if t >= step_at_s else 0.0))
    t_plant = np.array([s.t_s for s in states]) - step_at_s
    r_plant = np.array([s.yaw_rate_radps for s in states])
    after = t_plant >= 0.0

    def rhs(_t: float, x: np.ndarray) -> list[float]:
        return vehicle_dynamics_mb(list(x), [0.0, 0.0], BMW)

    start = init_mb([0.0, 0.0, steer, speed, 0.0, 0.0, 0.0], BMW)
    t_mb = np.linspace(0.0, 2.5, 2501)
    r_mb = solve_ivp(rhs, (0.0, 2.5), start, method="LSODA", rtol=1e-6, atol=1e-8,
                     t_eval=t_mb).y[5]
    for fraction, bound_s in ((0.5, 0.01), (0.63, 0.01), (0.9, 0.05)):
        plant_s = rise_time_s(t_plant[after], r_plant[after], fraction)
        reference_s = rise_time_s(t_mb, r_mb, fraction)
        assert plant_s == pytest.approx(reference_s, abs=bound_s), (fraction, plant_s,
                                                                     reference_s)
