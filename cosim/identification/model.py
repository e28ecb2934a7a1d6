"""The result of an identification: the plant seen through the controller's model family."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from cosim.identification.data import IdentificationError
from tracker.models.dynamic_bicycle import DynamicBicycleParams

BELIEF_FIELDS = ("mass_kg", "yaw_inertia_kgm2", "cog_front_m", "cog_rear_m",
                 "cornering_stiffness_front_npr", "cornering_stiffness_rear_npr",
                 "steer_time_constant_s")
"""The identified quantities that are ``tracker.model.*`` keys (the controller's belief)."""


@dataclass(frozen=True)
class IdentifiedModel:
    """Parameters of the bicycle models and actuator lags that best explain the plant.

    Every fitted value comes with the RMS of its fit's residual (model minus measurement,
    in the unit named) and the number of samples behind it. The dynamic bicycle is the
    linear-tyre model of Rajamani 2012, sec. 2.3 (:mod:`tracker.models.dynamic_bicycle`) with the
    known mass, yaw inertia and CoG position listed here and the fitted axle stiffnesses.
    """

    # Kinematic bicycle: low-speed steady circles.
    effective_wheelbase_m: float
    wheelbase_radius_residual_rms_m: float
    wheelbase_samples: int
    # Dynamic bicycle (linear tyres): steady turns and step steers.
    mass_kg: float
    yaw_inertia_kgm2: float
    cog_front_m: float
    cog_rear_m: float
    cornering_stiffness_front_npr: float
    cornering_stiffness_rear_npr: float
    understeer_gradient_degpg: float
    yaw_rate_gain_residual_rms_per_s: float
    yaw_rate_gain_samples: int
    transient_yaw_rate_residual_rms_radps: float
    transient_lateral_velocity_residual_rms_mps: float
    transient_samples: int
    max_lateral_accel_mps2: float
    """Largest steady lateral acceleration the cornering fit saw (its linear range)."""
    # Steering actuator: commanded vs measured road-wheel angle.
    steer_gain: float
    steer_time_constant_s: float
    steer_rate_limit_radps: float | None
    """None when the rate limit did not bind on the steering steps."""
    steer_delay_s: float
    steer_residual_rms_rad: float
    steer_samples: int
    # Longitudinal: commanded accel_mps2 (through AccelToTorque) vs measured ax_mps2.
    accel_gain: float
    accel_offset_mps2: float
    accel_time_constant_s: float
    accel_delay_s: float
    accel_residual_rms_mps2: float
    accel_samples: int

    def __post_init__(self) -> None:
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            if isinstance(value, float) and not math.isfinite(value):
                raise IdentificationError(f"IdentifiedModel.{field.name} = {value!r}: "
                                          "expected a finite number")

    def belief(self) -> dict[str, float]:
        """The controller's model of this plant: the ``tracker.model.*`` values identified
        (mass, yaw inertia, CoG position, axle cornering stiffnesses, steering lag), as a
        belief file holds them (``cosim identify --belief-out``)."""
        return {name: float(getattr(self, name)) for name in BELIEF_FIELDS}

    @property
    def understeer_gradient_radpmps2(self) -> float:
        """The understeer gradient in rad per m/s^2 ((S1) of :mod:`tracker.models.dynamic_bicycle`;
        Rajamani 2012, sec. 3.5)."""
        return self.dynamic_bicycle().understeer_gradient_radpmps2

    def dynamic_bicycle(self) -> DynamicBicycleParams:
        """The identified linear-tyre dynamic bicycle."""
        return DynamicBicycleParams(
            mass_kg=self.mass_kg,
            yaw_inertia_kgm2=self.yaw_inertia_kgm2,
            cog_front_m=self.cog_front_m,
            cog_rear_m=self.cog_rear_m,
            cornering_stiffness_front_npr=self.cornering_stiffness_front_npr,
            cornering_stiffness_rear_npr=self.cornering_stiffness_rear_npr,
        )

    def yaw_rate_gain_per_s(self, vx_mps: float) -> float:
        """Closed-form steady-state yaw-rate gain r/delta of the identified model [1/s]."""
        return self.dynamic_bicycle().yaw_rate_gain_per_s(vx_mps)

    def to_dict(self) -> dict[str, float | int | None]:
        """Every field by name (JSON-ready: plain numbers, ``None`` for no rate limit)."""
        return dataclasses.asdict(self)

    def table_rows(self) -> list[tuple[str, float | None, str, str]]:
        """``(quantity, value, unit, residual)`` for the command line's table."""
        def residual(rms: float, unit: str, samples: int) -> str:
            return f"rms {rms:.3g} {unit} (n = {samples})"

        wheelbase = residual(self.wheelbase_radius_residual_rms_m, "m radius",
                             self.wheelbase_samples)
        gain = residual(self.yaw_rate_gain_residual_rms_per_s, "1/s r/delta",
                        self.yaw_rate_gain_samples)
        transient = (f"rms {self.transient_yaw_rate_residual_rms_radps:.3g} rad/s r, "
                     f"{self.transient_lateral_velocity_residual_rms_mps:.3g} m/s vy "
                     f"(n = {self.transient_samples})")
        steer = residual(self.steer_residual_rms_rad, "rad", self.steer_samples)
        accel = residual(self.accel_residual_rms_mps2, "m/s^2", self.accel_samples)
        return [
            ("effective wheelbase", self.effective_wheelbase_m, "m", wheelbase),
            ("cornering stiffness front", self.cornering_stiffness_front_npr, "N/rad",
             transient),
            ("cornering stiffness rear", self.cornering_stiffness_rear_npr, "N/rad",
             transient),
            ("understeer gradient", self.understeer_gradient_degpg, "deg/g", gain),
            ("understeer gradient", self.understeer_gradient_radpmps2, "rad/(m/s^2)", gain),
            ("max lateral accel in fit", self.max_lateral_accel_mps2, "m/s^2", ""),
            ("steer gain", self.steer_gain, "", steer),
            ("steer time constant", self.steer_time_constant_s, "s", steer),
            ("steer rate limit", self.steer_rate_limit_radps, "rad/s",
             steer if self.steer_rate_limit_radps is not None else "did not bind"),
            ("steer delay", self.steer_delay_s, "s", steer),
            ("accel gain", self.accel_gain, "", accel),
            ("accel offset", self.accel_offset_mps2, "m/s^2", accel),
            ("accel time constant", self.accel_time_constant_s, "s", accel),
            ("accel delay", self.accel_delay_s, "s", accel),
        ]

