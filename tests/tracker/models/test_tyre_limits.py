"""The friction ellipse per axle (tracker.models.tyre_limits): numbers checkable by hand, and the
dynamic NMPC keeping its plan within it."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from cosim.core.exceptions import ConfigError
from cosim.core.vehicle_params import VehicleParams
from tests.named_vectors import named_vector
from tests.tracker.dynamic_closed_loop import Car, estimate_of
from tracker.config import TrackerConfig
from tracker.models.steered_dynamic_bicycle import INPUT, STATE, SteeredBicycleParams
from tracker.models.tyre_limits import (
    AIR_DENSITY_KGPM3,
    LIMIT_NAMES,
    friction_usage_function,
    usage_bounds,
)
from tracker.mpc.dynamic_nmpc import DynamicNmpc, dynamic_model
from tracker.paths.reference_path import ReferencePath
from tracker.paths.shapes import straight

G = 9.81
VEHICLE = VehicleParams()
PARAMS = SteeredBicycleParams.from_vehicle(VEHICLE)
MU = 0.6


def usage(vehicle: VehicleParams, state: dict[str, float], accel_mps2: float,
          steer_rad: float = 0.0) -> np.ndarray:
    x = named_vector(STATE, road_wheel_angle_rad=steer_rad, **state)
    u = named_vector(INPUT, accel_mps2=accel_mps2)
    h = friction_usage_function(vehicle, SteeredBicycleParams.from_vehicle(vehicle), MU)
    return np.asarray(h(x, u), dtype=float).ravel()


def resistance_n(vehicle: VehicleParams, vx: float) -> float:
    return (0.5 * AIR_DENSITY_KGPM3 * vehicle.drag_area_m2 * vx * vx
            + vehicle.rolling_resistance * vehicle.mass_kg * G)


def test_accelerating_straight_loads_only_the_driven_rear_axle() -> None:
    """RWD at 20 m/s, 2 m/s^2: the rear carries ``m a + drag + rolling`` on a load raised
    by ``m a h / L``; the front axle carries nothing."""
    m, h, length = VEHICLE.mass_kg, VEHICLE.cog_height_m, VEHICLE.wheelbase_m
    force = m * 2.0 + resistance_n(VEHICLE, 20.0)
    load = m * (G * VEHICLE.cog_front_m + 2.0 * h) / length
    front, rear = usage(VEHICLE, {"vx_mps": 20.0}, 2.0)
    assert front == pytest.approx(0.0, abs=1e-12)
    assert rear == pytest.approx((force / (MU * load)) ** 2, rel=1e-9)


@pytest.mark.parametrize("drive, front_share", [("fwd", 1.0), ("awd", 0.5)])
def test_drive_force_goes_to_the_driven_axles(drive: str, front_share: float) -> None:
    vehicle = dataclasses.replace(VEHICLE, drive=drive)
    m, h, length = vehicle.mass_kg, vehicle.cog_height_m, vehicle.wheelbase_m
    force = m * 1.0 + resistance_n(vehicle, 10.0)
    load_front = m * (G * vehicle.cog_rear_m - 1.0 * h) / length
    front, _ = usage(vehicle, {"vx_mps": 10.0}, 1.0)
    assert front == pytest.approx((front_share * force / (MU * load_front)) ** 2, rel=1e-9)


def test_braking_in_proportion_to_the_loads_uses_both_axles_alike() -> None:
    """Ideal braking: each axle's share of the braking force is its share of the load, so
    both use ``|F_x| / (mu m g)`` of their grip."""
    accel = -4.0
    force = VEHICLE.mass_kg * accel + resistance_n(VEHICLE, 15.0)
    expected = (force / (MU * VEHICLE.mass_kg * G)) ** 2
    front, rear = usage(VEHICLE, {"vx_mps": 15.0}, accel)
    assert front == pytest.approx(expected, rel=1e-9)
    assert rear == pytest.approx(expected, rel=1e-9)


def test_steady_turn_uses_lateral_acceleration_over_mu_g_on_the_front_axle() -> None:
    """In the linear model's steady turn each axle's lateral force is its static load's
    share of ``m a_y``, so the front axle uses ``(a_y / (mu g))^2`` of its grip."""
    steer = 0.02
    steady = PARAMS.bicycle.steady_state(20.0, steer)
    state = {"vx_mps": 20.0, "vy_mps": steady["vy_mps"],
             "yaw_rate_radps": steady["yaw_rate_radps"]}
    front, rear = usage(VEHICLE, state, 0.0, steer)
    assert front == pytest.approx((steady["ay_mps2"] / (MU * G)) ** 2, rel=1e-6)
    lateral_rear = VEHICLE.mass_kg * steady["ay_mps2"] * VEHICLE.cog_front_m / VEHICLE.wheelbase_m
    grip_rear = MU * VEHICLE.mass_kg * G * VEHICLE.cog_front_m / VEHICLE.wheelbase_m
    assert rear == pytest.approx((lateral_rear**2 + resistance_n(VEHICLE, 20.0) ** 2)
                                 / grip_rear**2, rel=1e-6)


def test_bad_inputs_are_refused() -> None:
    with pytest.raises(ConfigError, match="friction"):
        friction_usage_function(VEHICLE, PARAMS, 0.0)
    with pytest.raises(ConfigError, match="usage_max"):
        usage_bounds(1.5)
    assert usage_bounds(0.8) == pytest.approx((0.64, 0.64))


@pytest.mark.parametrize("friction, expected", [(1.0, False), (0.89, True), (0.6, True)])
def test_tyre_limits_join_the_nlp_below_the_friction_threshold(friction: float,
                                                                expected: bool) -> None:
    config = TrackerConfig(name="dynamic-nmpc",
                           model=dataclasses.replace(VEHICLE, tyre_friction=friction))
    model = dynamic_model(config)
    assert (model.stage_limits is not None) is expected
    if expected:
        assert model.stage_limit_names == LIMIT_NAMES
    off = dataclasses.replace(config, grip=dataclasses.replace(config.grip, tyre_limits=False))
    assert dynamic_model(off).stage_limits is None


def planned_accel(tyre_limits: bool) -> float:
    """The highest acceleration of the dynamic NMPC's first plan on a straight at 15 m/s
    with a 20 m/s reference, believing friction 0.6."""
    config = TrackerConfig(
        name="dynamic-nmpc",
        model=dataclasses.replace(VEHICLE, tyre_friction=MU),
        grip=dataclasses.replace(TrackerConfig().grip, tyre_limits=tyre_limits),
    )
    tracker = DynamicNmpc(config)
    path = straight(300.0)
    reference = ReferencePath(path.x_m, path.y_m, 20.0)
    estimate = estimate_of(0.0, Car(0.0, 0.0, 0.0, 15.0))
    _, plan = tracker.step(0.0, estimate, reference)
    assert plan.success
    return float(np.max(plan.column("accel_mps2")))


def test_nmpc_accelerates_within_the_rear_axles_grip() -> None:
    """Without the limit the plan takes the 3 m/s^2 bound; with it, the acceleration whose
    rear-axle force is ``usage_max mu F_zr`` (solved by hand from (T1)-(T4)), to within the
    soft penalty's give."""
    m, h, length = VEHICLE.mass_kg, VEHICLE.cog_height_m, VEHICLE.wheelbase_m
    share = TrackerConfig().grip.usage_max * MU
    resistance = resistance_n(VEHICLE, 15.0)
    # m a + F_res = share m (g l_f + a h) / L  ->  a
    limit = ((share * m * G * VEHICLE.cog_front_m / length - resistance)
             / (m - share * m * h / length))
    assert planned_accel(tyre_limits=False) == pytest.approx(3.0, abs=1e-3)
    limited = planned_accel(tyre_limits=True)
    assert 0.9 * limit < limited < 1.05 * limit, (limited, limit)
