"""The friction ellipse per axle (tracker.models.tyre_limits): numbers checkable by hand, and the
dynamic NMPC keeping its plan within it."""

from __future__ import annotations

import dataclasses

import casadi as ca
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
    DRIVE_BLEND_N,
    LIMIT_NAMES,
    friction_usage_function,
    usage_bounds,
)
from tracker.mpc.dynamic_nmpc import DynamicNmpc, dynamic_model
from tracker.mpc.nmpc_problem import TYRE_EXCESS_BLEND, smooth_excess
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


def split(force_n: float) -> tuple[float, float]:
    """The drive and brake parts of ``F_x`` as (T3') blends them (``e``: DRIVE_BLEND_N)."""
    root = np.hypot(force_n, DRIVE_BLEND_N)
    return 0.5 * (force_n + root), 0.5 * (force_n - root)


def axle_forces_x(vehicle: VehicleParams, force_n: float, accel_mps2: float,
                  front_share: float) -> tuple[float, float]:
    """(T3): each axle's share of the drive part, and of the brake part its load's share."""
    m, h, length = vehicle.mass_kg, vehicle.cog_height_m, vehicle.wheelbase_m
    load_front = m * (G * vehicle.cog_rear_m - accel_mps2 * h) / length
    load_rear = m * (G * vehicle.cog_front_m + accel_mps2 * h) / length
    drive, brake = split(force_n)
    weight = m * G
    return (front_share * drive + brake * load_front / weight,
            (1.0 - front_share) * drive + brake * load_rear / weight)


def test_the_drive_and_brake_parts_blend_over_a_few_newtons() -> None:
    """(T3'): far from zero the parts are max(F_x, 0) and min(F_x, 0) to e^2 / (4 |F_x|)."""
    for force in (-3000.0, -500.0, 500.0, 3000.0):
        drive, brake = split(force)
        assert drive + brake == pytest.approx(force, rel=1e-12)
        assert abs(drive - max(force, 0.0)) <= DRIVE_BLEND_N**2 / (4 * abs(force)) * 1.0001
    assert split(0.0) == pytest.approx((DRIVE_BLEND_N / 2, -DRIVE_BLEND_N / 2))


def test_accelerating_straight_loads_only_the_driven_rear_axle() -> None:
    """RWD at 20 m/s, 2 m/s^2: the rear carries ``m a + drag + rolling`` on a load raised
    by ``m a h / L``; the front axle carries only the blend's few newtons of braking."""
    m, h, length = VEHICLE.mass_kg, VEHICLE.cog_height_m, VEHICLE.wheelbase_m
    force = m * 2.0 + resistance_n(VEHICLE, 20.0)
    load_front = m * (G * VEHICLE.cog_rear_m - 2.0 * h) / length
    load = m * (G * VEHICLE.cog_front_m + 2.0 * h) / length
    front_x, rear_x = axle_forces_x(VEHICLE, force, 2.0, 0.0)
    front, rear = usage(VEHICLE, {"vx_mps": 20.0}, 2.0)
    assert front == pytest.approx((front_x / (MU * load_front)) ** 2, rel=1e-9)
    assert front < 1e-9
    assert rear == pytest.approx((rear_x / (MU * load)) ** 2, rel=1e-9)
    assert rear == pytest.approx((force / (MU * load)) ** 2, rel=1e-3)  # the exact split


@pytest.mark.parametrize("drive, front_share", [("fwd", 1.0), ("awd", 0.5)])
def test_drive_force_goes_to_the_driven_axles(drive: str, front_share: float) -> None:
    vehicle = dataclasses.replace(VEHICLE, drive=drive)
    m, h, length = vehicle.mass_kg, vehicle.cog_height_m, vehicle.wheelbase_m
    force = m * 1.0 + resistance_n(vehicle, 10.0)
    load_front = m * (G * vehicle.cog_rear_m - 1.0 * h) / length
    front_x, _ = axle_forces_x(vehicle, force, 1.0, front_share)
    front, _ = usage(vehicle, {"vx_mps": 10.0}, 1.0)
    assert front == pytest.approx((front_x / (MU * load_front)) ** 2, rel=1e-9)
    assert front == pytest.approx((front_share * force / (MU * load_front)) ** 2, rel=1e-3)


def test_braking_in_proportion_to_the_loads_uses_both_axles_alike() -> None:
    """Ideal braking: each axle's share of the braking force is its share of the load, so
    both use ``|F_x| / (mu m g)`` of their grip."""
    accel = -4.0
    m, h, length = VEHICLE.mass_kg, VEHICLE.cog_height_m, VEHICLE.wheelbase_m
    force = m * accel + resistance_n(VEHICLE, 15.0)
    expected = (force / (MU * m * G)) ** 2
    front_x, rear_x = axle_forces_x(VEHICLE, force, accel, 0.0)
    load_front = m * (G * VEHICLE.cog_rear_m - accel * h) / length
    load_rear = m * (G * VEHICLE.cog_front_m + accel * h) / length
    front, rear = usage(VEHICLE, {"vx_mps": 15.0}, accel)
    assert front == pytest.approx((front_x / (MU * load_front)) ** 2, rel=1e-9)
    assert rear == pytest.approx((rear_x / (MU * load_rear)) ** 2, rel=1e-9)
    assert front == pytest.approx(expected, rel=1e-3)
    assert rear == pytest.approx(expected, rel=1e-3)


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
    _, rear_x = axle_forces_x(VEHICLE, resistance_n(VEHICLE, 20.0), 0.0, 0.0)
    assert rear == pytest.approx((lateral_rear**2 + rear_x**2) / grip_rear**2, rel=1e-6)


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


def test_the_excess_penalty_has_a_continuous_curvature_at_the_bound() -> None:
    """The NLP's penalty on the usage's excess, ``smooth_excess(over)^2``: its second
    derivative is continuous where the exact ``max(over, 0)^2``'s jumps from 0 to 2 (the jump
    that made fatrop cycle), it never falls as the excess grows, and away from the bound it
    is the exact excess to within ``e^2 / (4 |over|)``."""
    over = ca.SX.sym("over")
    penalty = smooth_excess(over) ** 2
    curvature = ca.Function("c", [over], [ca.hessian(penalty, over)[0]])
    slope = ca.Function("s", [over], [ca.gradient(penalty, over)])
    e = TYRE_EXCESS_BLEND
    steps = [float(curvature(z)) for z in np.linspace(-e, e, 201)]
    assert max(abs(b - a) for a, b in zip(steps, steps[1:], strict=False)) < 0.1
    assert all(float(slope(z)) >= 0.0 for z in np.linspace(-0.5, 0.5, 101))
    value = ca.Function("v", [over], [smooth_excess(over)])
    for z in (-0.2, -0.05, 0.05, 0.2):
        assert abs(float(value(z)) - max(z, 0.0)) <= e * e / (4 * abs(z)) * 1.0001
    exact = ca.Function("x", [over], [ca.hessian(ca.fmax(over, 0.0) ** 2, over)[0]])
    assert float(exact(-1e-9)) == 0.0 and float(exact(1e-9)) == 2.0  # the jump it replaces
