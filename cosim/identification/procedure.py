"""The identification procedure: which manoeuvres, in which order, feeding which fit.

1. Low-speed steady circles at several steering angles -> effective wheelbase of the
   kinematic bicycle (:func:`~cosim.identification.fits.fit_wheelbase`).
2. Steady turns at several speeds, slowest first, in the tyres' linear range (a lateral
   acceleration of ``lateral_accel_g``, at most ``linear_friction_share`` of the friction
   limit), steered by ``delta = (L / v^2 + K) a_y`` with the effective wheelbase and the
   understeer gradient measured on the slower turns, and re-steered once if the car still
   misses the lateral acceleration by more than :data:`RESTEER_TOLERANCE`; then a step
   steer of the same angle at each speed -> axle cornering stiffnesses of the linear-tyre
   dynamic bicycle and its understeer gradient
   (:func:`~cosim.identification.fits.fit_cornering_stiffness`).
3. A small and a large steering step at low speed -> gain, time constant, dead time and
   rate limit of the steering actuator, from commanded vs measured road-wheel angle.
4. Acceleration steps, drive then brake, on a straight road (at most
   ``longitudinal_friction_share`` of the friction limit: about half the grip of a driven
   axle that carries 43 % of the weight), through :class:`~cosim.plant.low_level.AccelToTorque`
   with the controller's belief -> gain, offset, time constant and dead time from
   commanded ``accel_mps2`` to measured ``ax_mps2``.

The design of the manoeuvres uses what a test engineer knows of the car before testing:
its mass, yaw inertia and CoG position (which the dynamic bicycle takes as known), the
steering limit and the road's friction coefficient.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from cosim.core.physical_constants import GRAVITY_MPS2
from cosim.core.vehicle_params import PlantConfig, VehicleParams
from cosim.identification.data import IdentificationError, SteadyTurn
from cosim.identification.fits import fit_cornering_stiffness, fit_first_order_lag, fit_wheelbase
from cosim.identification.manoeuvres import (
    Rig,
    accel_steps,
    steady_turn,
    steering_step,
    step_steer,
)
from cosim.identification.model import IdentifiedModel

STEER_LIMIT_SHARE = 0.8
"""No manoeuvre asks for more than this share of the steering limit ``max_steer_rad``."""

RESTEER_TOLERANCE = 0.25
"""A steady turn whose lateral acceleration misses the target by more than this share is
driven again with the steering scaled by target over measured."""


@dataclass(frozen=True)
class IdentificationSettings:
    """The manoeuvres' speeds, angles, amplitudes and durations (SI)."""

    circle_speed_mps: float = 1.5
    circle_steer_rad: tuple[float, ...] = (0.05, 0.1, 0.15, 0.2)
    cornering_speeds_mps: tuple[float, ...] = (10.0, 15.0, 20.0, 25.0, 30.0)
    lateral_accel_g: float = 0.25
    linear_friction_share: float = 0.4
    longitudinal_friction_share: float = 0.2
    settle_s: float = 3.0
    window_s: float = 1.0
    step_steer_duration_s: float = 2.5
    sample_period_s: float = 0.01
    steering_speed_mps: float = 3.0
    steering_steps_rad: tuple[float, ...] = (0.01, 0.25)
    steering_step_duration_s: float = 1.5
    accel_speed_mps: float = 15.0
    accel_steps_mps2: tuple[float, ...] = (1.5, -2.0)
    accel_hold_s: float = 1.5

    def __post_init__(self) -> None:
        positive = ("circle_speed_mps", "lateral_accel_g", "linear_friction_share",
                "longitudinal_friction_share",
                    "settle_s", "window_s", "step_steer_duration_s", "sample_period_s",
                    "steering_speed_mps", "steering_step_duration_s", "accel_speed_mps",
                    "accel_hold_s")
        for name in positive:
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0.0):
                raise IdentificationError(f"IdentificationSettings.{name} = {value!r}: "
                                          "expected a positive number")
        tuples = {"circle_steer_rad": 1, "cornering_speeds_mps": 1, "steering_steps_rad": 1,
                  "accel_steps_mps2": 1}
        for name, minimum in tuples.items():
            values = getattr(self, name)
            if len(values) < minimum or not all(math.isfinite(v) and v != 0.0 for v in values):
                raise IdentificationError(f"IdentificationSettings.{name} = {values!r}: "
                                          "expected non-zero finite numbers")
        if min(self.cornering_speeds_mps) <= 0.0:
            raise IdentificationError(
                f"IdentificationSettings.cornering_speeds_mps = {self.cornering_speeds_mps}: "
                "expected forward speeds > 0")


def _cap(steer_rad: float, plant: PlantConfig) -> float:
    limit = STEER_LIMIT_SHARE * plant.max_steer_rad
    return max(-limit, min(limit, steer_rad))


def identify(plant: PlantConfig, belief: VehicleParams, physics_dt_s: float,
             settings: IdentificationSettings | None = None) -> IdentifiedModel:
    """Drive the plant of ``plant`` through the manoeuvres and fit every model.

    ``belief`` is the controller's model of the car that :class:`AccelToTorque` uses to
    turn acceleration demands into torques (``tracker.model`` of a scenario).
    """
    settings = settings if settings is not None else IdentificationSettings()
    rig = Rig(plant=plant, belief=belief, physics_dt_s=physics_dt_s)
    window = {"settle_s": settings.settle_s, "window_s": settings.window_s}

    circles = [steady_turn(rig, settings.circle_speed_mps, _cap(steer, plant), **window)
               for steer in settings.circle_steer_rad]
    wheelbase = fit_wheelbase(circles, plant.cog_rear_m / plant.wheelbase_m)

    accel_target = GRAVITY_MPS2 * min(settings.lateral_accel_g,
                                      settings.linear_friction_share * plant.tyre_friction)
    turns: list[SteadyTurn] = []
    steps = []
    gradients: list[float] = []
    for speed in sorted(settings.cornering_speeds_mps):
        # delta = (L / v^2 + K) a_y, with K measured on the slower turns so far (S1-S2).
        gradient = sum(gradients) / len(gradients) if gradients else 0.0
        steer = _cap((wheelbase.effective_wheelbase_m / speed**2 + gradient) * accel_target,
                     plant)
        turn = steady_turn(rig, speed, steer, **window)
        if abs(abs(turn.ay_mps2) / accel_target - 1.0) > RESTEER_TOLERANCE:
            steer = _cap(steer * accel_target / max(abs(turn.ay_mps2), 1e-3), plant)
            turn = steady_turn(rig, speed, steer, **window)
        turns.append(turn)
        lateral_accel = turn.vx_mps * turn.yaw_rate_radps
        gradients.append((turn.steer_rad - wheelbase.effective_wheelbase_m
                          * turn.yaw_rate_radps / turn.vx_mps) / lateral_accel)
        steps.append(step_steer(rig, speed, steer, duration_s=settings.step_steer_duration_s,
                                sample_period_s=settings.sample_period_s))
    cornering = fit_cornering_stiffness(turns, steps, plant)

    steering = fit_first_order_lag(
        [steering_step(rig, settings.steering_speed_mps, _cap(step, plant),
                       duration_s=settings.steering_step_duration_s)
         for step in settings.steering_steps_rad],
        fit_rate_limit=True,
    )
    accel_limit = settings.longitudinal_friction_share * plant.tyre_friction * GRAVITY_MPS2
    demands = tuple(math.copysign(min(abs(a), accel_limit), a)
                    for a in settings.accel_steps_mps2)
    longitudinal = fit_first_order_lag(
        [accel_steps(rig, settings.accel_speed_mps, demands, hold_s=settings.accel_hold_s)],
        fit_offset=True,
    )

    model = cornering.model
    return IdentifiedModel(
        effective_wheelbase_m=wheelbase.effective_wheelbase_m,
        wheelbase_radius_residual_rms_m=wheelbase.radius_residual_rms_m,
        wheelbase_samples=wheelbase.samples,
        mass_kg=model.mass_kg,
        yaw_inertia_kgm2=model.yaw_inertia_kgm2,
        cog_front_m=model.cog_front_m,
        cog_rear_m=model.cog_rear_m,
        cornering_stiffness_front_npr=model.cornering_stiffness_front_npr,
        cornering_stiffness_rear_npr=model.cornering_stiffness_rear_npr,
        understeer_gradient_degpg=model.understeer_gradient_degpg,
        yaw_rate_gain_residual_rms_per_s=cornering.yaw_rate_gain_residual_rms_per_s,
        yaw_rate_gain_samples=cornering.steady_samples,
        transient_yaw_rate_residual_rms_radps=cornering.transient_yaw_rate_residual_rms_radps,
        transient_lateral_velocity_residual_rms_mps=(
            cornering.transient_lateral_velocity_residual_rms_mps),
        transient_samples=cornering.transient_samples,
        max_lateral_accel_mps2=max(abs(t.ay_mps2) for t in turns),
        steer_gain=steering.gain,
        steer_time_constant_s=steering.time_constant_s,
        steer_rate_limit_radps=steering.rate_limit_per_s,
        steer_delay_s=steering.delay_s,
        steer_residual_rms_rad=steering.residual_rms,
        steer_samples=steering.samples,
        accel_gain=longitudinal.gain,
        accel_offset_mps2=longitudinal.offset,
        accel_time_constant_s=longitudinal.time_constant_s,
        accel_delay_s=longitudinal.delay_s,
        accel_residual_rms_mps2=longitudinal.residual_rms,
        accel_samples=longitudinal.samples,
    )
