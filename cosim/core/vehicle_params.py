"""The one record of vehicle parameters: the plant's truth and a controller's belief.

The plant is built from ``plant`` (a :class:`PlantConfig`, which is a :class:`VehicleParams`
plus how the plant is simulated); a tracker's internal model reads ``tracker.model`` (a
:class:`VehicleParams`). Both default to the sedan of The MathWorks' lane-keeping MPC example
("Lane Keeping Assist System Using Model Predictive Control", Model Predictive Control
Toolbox documentation): m = 1575 kg, I_z = 2875 kg m^2, l_f = 1.2 m, l_r = 1.6 m). Model mismatch
is the difference between the two records, stated as data.

The steering actuator (``steer_time_constant_s``, ``max_steer_rate_radps``) is the plant's
truth in ``plant`` and a tracker's belief in ``tracker.model``. The axle cornering
stiffnesses are a belief for dynamic models only (the plant's own tyres are the Pacejka
model in ``plant.tyre``); their defaults are what ``cosim identify`` finds on the default
sedan (C_f = 72 550 N/rad, C_r = 79 580 N/rad, understeer gradient 2.2 deg/g), not that
example's C_f = 19 000 and C_r = 33 000 N/rad, which a user can still state as a
belief (``--set tracker.model.cornering_stiffness_front_npr=19000``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from cosim.core.config_fields import section, setting
from cosim.core.exceptions import ConfigError
from cosim.core.physical_constants import GRAVITY_MPS2
from cosim.core.slip_control_params import SlipControlParams
from cosim.core.suspension_params import SuspensionParams
from cosim.core.tyre_params import TyreParams

MIN_TRACK_M = 0.5
MAX_TRACK_M = 3.0
"""Bounds of a track (a narrow city car's is about 1.3 m, a heavy truck's about 2 m) [m]."""

BRAKE_DESIGN_DECEL_G = 0.5
"""The brake balance distributes torque as the axle loads at this deceleration (ideal
braking, Gillespie, "Fundamentals of Vehicle Dynamics", ch. 3): front share
``(l_r + h a/g) / L``, 0.67 for the sedan [g] (:attr:`CarParams.brake_front_share`)."""

MAX_STEER_BOUND_RAD = 1.5
"""Upper bound of a road-wheel angle limit (86 deg): short of pi/2, where the bicycle
model's ``tan(delta)`` has its pole. The car's own geometry bounds it further: the inner
front wheel's Ackermann angle stays below 90 deg (:meth:`VehicleParams.__post_init__`;
1.29 rad for the default sedan). A bound of 1.0 rad, kept from the first plant without a
reason, was below CommonRoad's BMW 320i parameter set (1.066 rad) [rad]."""


@dataclass(frozen=True)
class CarParams:
    """Physical parameters of the car (all SI) that the plant and a controller's belief
    share; :class:`VehicleParams` (the belief) adds what only a controller's model uses."""

    mass_kg: float = setting(1575.0, low=100.0, high=20000.0, doc="total mass incl. wheels")
    yaw_inertia_kgm2: float = setting(2875.0, low=10.0, high=1e6, doc="about the CoG, total")
    cog_front_m: float = setting(1.2, low=0.05, high=5.0, doc="CoG to front axle (l_f)")
    cog_rear_m: float = setting(1.6, low=0.05, high=5.0, doc="CoG to rear axle (l_r)")
    track_m: float = setting(
        1.6, low=MIN_TRACK_M, high=MAX_TRACK_M,
        doc="distance between the left and right wheels of both axles, unless "
        "track_front_m / track_rear_m say otherwise",
    )
    track_front_m: float = setting(
        0.0, low=0.0, high=MAX_TRACK_M,
        doc="front axle's track (wheel centres); 0: track_m",
    )
    track_rear_m: float = setting(
        0.0, low=0.0, high=MAX_TRACK_M, doc="rear axle's track; 0: track_m"
    )
    cog_height_m: float = setting(0.55, low=0.1, high=2.0, doc="CoG above the ground")
    wheel_radius_m: float = setting(0.31, low=0.1, high=1.0, doc="rolling radius")
    wheel_mass_kg: float = setting(20.0, low=1.0, high=200.0, doc="each wheel, part of mass_kg")
    wheel_inertia_kgm2: float = setting(1.0, low=0.05, high=20.0, doc="each wheel about its axle")
    tyre_friction: float = setting(
        1.0, low=0.05, high=2.0,
        doc="tyre-road peak friction coefficient, both directions; the plant's Magic Formula "
        "tyres scale it per direction by plant.tyre.longitudinal_friction_scale and "
        "lateral_friction_scale (1: isotropic)",
    )
    max_steer_rad: float = setting(
        0.5236,
        low=0.05,
        high=MAX_STEER_BOUND_RAD,
        doc="road-wheel (bicycle-model) angle limit; the inner front wheel's Ackermann angle "
        "must stay below 90 deg: tan(max_steer_rad) < 2 wheelbase / front track",
    )
    drive: str = setting("rwd", choices=("rwd", "fwd", "awd"), doc="driven axle(s)")
    max_drive_torque_nm: float = setting(4000.0, low=0.0, high=50000.0, doc="at the wheels, total")
    max_drive_power_w: float = setting(150e3, low=1e3, high=2e6, doc="at the wheels")
    max_brake_torque_nm: float = setting(8000.0, low=0.0, high=100000.0, doc="all wheels, total")
    drag_area_m2: float = setting(0.66, low=0.0, high=10.0, doc="drag coefficient x frontal area")
    rolling_resistance: float = setting(0.012, low=0.0, high=0.1, doc="coefficient, force/weight")
    steer_time_constant_s: float = setting(
        0.05, low=0.0, high=1.0, doc="first-order lag of the steering actuator"
    )
    max_steer_rate_radps: float = setting(
        0.8, low=0.05, high=10.0, doc="rate limit of the steering actuator"
    )
    def __post_init__(self) -> None:
        if 4 * self.wheel_mass_kg >= self.mass_kg:
            raise ConfigError(
                f"wheel_mass_kg = {self.wheel_mass_kg}: expected four wheels lighter than "
                f"mass_kg = {self.mass_kg}"
            )
        for name in ("track_front_m", "track_rear_m"):
            value = getattr(self, name)
            if 0.0 < value < MIN_TRACK_M:
                raise ConfigError(
                    f"{name} = {value}: expected 0 (track_m) or a track in "
                    f"[{MIN_TRACK_M:g}, {MAX_TRACK_M:g}] m"
                )
        front_track = self.axle_tracks_m[0]
        lock = math.atan(2.0 * self.wheelbase_m / front_track)
        if self.max_steer_rad >= lock:
            raise ConfigError(
                f"max_steer_rad = {self.max_steer_rad}: expected less than {lock:.4f} rad, "
                f"where the inner front wheel's Ackermann angle reaches 90 deg (tan = 2 "
                f"wheelbase / front track = 2 x {self.wheelbase_m:g} / {front_track:g})"
            )

    @property
    def wheelbase_m(self) -> float:
        """Distance between the axles, l_f + l_r."""
        return self.cog_front_m + self.cog_rear_m

    @property
    def brake_front_share(self) -> float:
        """The front axle's share of the brake torque: the axle loads' split at
        :data:`BRAKE_DESIGN_DECEL_G`, ``(l_r + h a/g) / L`` (a fixed brake balance)."""
        return (self.cog_rear_m + self.cog_height_m * BRAKE_DESIGN_DECEL_G) / self.wheelbase_m

    @property
    def static_wheel_loads_n(self) -> tuple[float, float]:
        """One front and one rear wheel's load at rest on level ground, ``m g l_r / (2 L)``
        and ``m g l_f / (2 L)`` [N]."""
        weight_n = self.mass_kg * GRAVITY_MPS2
        return (weight_n * self.cog_rear_m / self.wheelbase_m / 2.0,
                weight_n * self.cog_front_m / self.wheelbase_m / 2.0)

    @property
    def axle_tracks_m(self) -> tuple[float, float]:
        """The front and the rear axle's track: ``track_front_m`` and ``track_rear_m``,
        each ``track_m`` where it is 0 [m]."""
        return (self.track_front_m or self.track_m, self.track_rear_m or self.track_m)

    @property
    def widest_track_m(self) -> float:
        """The wider of the two axles' tracks (the body is drawn and measured around it) [m]."""
        return max(self.axle_tracks_m)


@dataclass(frozen=True)
class VehicleParams(CarParams):
    """A controller's belief about the car (``tracker.model``): :class:`CarParams` plus the
    axle cornering stiffnesses of its linear-tyre models. The plant has no such keys (its
    tyres are the Magic Formula of ``plant.tyre``): ``plant.cornering_stiffness_*`` is
    refused with its new name (:data:`MOVED_PLANT_KEYS`)."""

    cornering_stiffness_front_npr: float = setting(
        72550.0,
        low=1e3,
        high=1e6,
        doc="front-axle cornering stiffness (both tyres), belief for dynamic models; the "
        "plant's own tyres are the Pacejka model in `plant.tyre` [N/rad]",
    )
    cornering_stiffness_rear_npr: float = setting(
        79580.0,
        low=1e3,
        high=1e6,
        doc="rear-axle cornering stiffness (both tyres), belief for dynamic models; the "
        "plant's own tyres are the Pacejka model in `plant.tyre` [N/rad]",
    )


MOVED_PLANT_KEYS: dict[str, str] = {
    "cornering_stiffness_front_npr": "tracker.model.cornering_stiffness_front_npr",
    "cornering_stiffness_rear_npr": "tracker.model.cornering_stiffness_rear_npr",
}
"""Keys that were accepted under ``plant.`` although only a controller's model reads them,
and where they live now."""


@dataclass(frozen=True)
class PlantConfig(CarParams):
    """The simulated car: its true parameters and how it is simulated."""

    actuator_delay_s: float = setting(0.0, low=0.0, high=2.0, doc="command transport delay")
    tyre_model: str = setting(
        "pacejka",
        choices=("pacejka", "contact"),
        doc="pacejka: Magic Formula tyres (cosim.plant.tyre_model) on frictionless wheel contacts; "
        "contact: MuJoCo's contact friction as the tyres (no cornering stiffness)",
    )
    tyre: TyreParams = section(TyreParams)
    slip_control: SlipControlParams = section(SlipControlParams)
    suspension: SuspensionParams = section(SuspensionParams)
    front_cornering_stiffness_scale: float = setting(
        0.77,
        low=0.05,
        high=5.0,
        doc="effective front-axle cornering stiffness / the tyre's (pacejka only): stands in "
        "for the steering compliance and roll steer the model lacks",
    )
    rear_cornering_stiffness_scale: float = setting(
        1.0, low=0.05, high=5.0, doc="effective rear-axle cornering stiffness / the tyre's"
    )
