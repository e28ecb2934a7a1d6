"""A lead car for adaptive cruise control: a kinematic car driving ahead of the ego car.

The lead car drives along the straight line of the ego car's initial heading, ``gap`` ahead
of the ego's initial CoG and ``lateral_offset`` to its left, with a prescribed speed
profile: it starts at ``initial_speed_mps`` and follows a piecewise-constant acceleration
(``accel_profile``: from each ``t_s`` on, ``accel_mps2``, until the next entry). It never
reverses: a braking lead car stops and stays stopped.

In MuJoCo it is ``models/lead_car.xml`` attached to the sedan (a mocap body without mass
or colliding geoms, :func:`cosim.plant.sedan_model.build_sedan`);
:class:`cosim.plant.car.MujocoPlant` advances :func:`advance_lead_car` every physics step
and sets the mocap pose from it. Off by default (``MujocoPlant(..., lead_car=None)``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from cosim.core.exceptions import ConfigError


@dataclass(frozen=True)
class LeadCarConfig:
    """Where the lead car starts and how it drives (see the module docstring)."""

    gap_m: float = 40.0
    """Distance of the lead car's centre ahead of the ego car's initial CoG, along the ego's
    initial heading [m]."""
    lateral_offset_m: float = 0.0
    """Offset of its path to the left of the ego car's initial heading line [m]."""
    initial_speed_mps: float = 20.0
    """Speed at t = 0 [m/s]."""
    accel_profile: tuple[tuple[float, float], ...] = ()
    """``(t_s, accel_mps2)`` pairs in increasing time: from ``t_s`` on the lead car
    accelerates at ``accel_mps2`` (before the first pair: 0). A change takes effect at the
    first physics step that starts at or after its time."""

    def __post_init__(self) -> None:
        for name in ("gap_m", "lateral_offset_m", "initial_speed_mps"):
            value = getattr(self, name)
            if not math.isfinite(value):
                raise ConfigError(f"lead_car.{name} = {value!r}: expected a finite number")
        if self.initial_speed_mps < 0.0:
            raise ConfigError(
                f"lead_car.initial_speed_mps = {self.initial_speed_mps}: expected >= 0"
            )
        previous = -math.inf
        for entry in self.accel_profile:
            if len(entry) != 2 or not all(math.isfinite(v) for v in entry):
                raise ConfigError(
                    f"lead_car.accel_profile entry {entry!r}: expected (t_s, accel_mps2), "
                    "two finite numbers"
                )
            if entry[0] <= previous:
                raise ConfigError(
                    f"lead_car.accel_profile = {self.accel_profile!r}: expected strictly "
                    "increasing times"
                )
            previous = entry[0]

    def accel_at(self, t_s: float) -> float:
        """The profile's acceleration at ``t_s`` [m/s^2]."""
        accel = 0.0
        for start_s, value in self.accel_profile:
            if t_s + 1e-12 < start_s:
                break
            accel = value
        return accel


@dataclass(frozen=True)
class LeadCarState:
    """The lead car at ``t_s``: its centre in the world frame (ENU) and its motion."""

    t_s: float
    x_m: float
    y_m: float
    yaw_rad: float
    speed_mps: float
    accel_mps2: float
    """Acceleration over the step that ended at ``t_s`` (0 once stopped) [m/s^2]."""
    distance_m: float
    """Distance driven since t = 0 [m]."""
    rear_x_m: float
    """World position of the centre of its rear bumper (site ``lead_car/rear_bumper``)."""
    rear_y_m: float

    def to_message(self) -> dict[str, float]:
        return {name: getattr(self, name) for name in self.__dataclass_fields__}


@dataclass(frozen=True)
class LeadCarPath:
    """The straight line the lead car drives on: its start and heading (world frame)."""

    start_x_m: float
    start_y_m: float
    yaw_rad: float
    rear_overhang_m: float
    """Distance from the car's centre back to its rear bumper [m]."""

    def state(self, t_s: float, distance_m: float, speed_mps: float,
              accel_mps2: float) -> LeadCarState:
        cos_yaw, sin_yaw = math.cos(self.yaw_rad), math.sin(self.yaw_rad)
        x = self.start_x_m + distance_m * cos_yaw
        y = self.start_y_m + distance_m * sin_yaw
        return LeadCarState(
            t_s=t_s,
            x_m=x,
            y_m=y,
            yaw_rad=self.yaw_rad,
            speed_mps=speed_mps,
            accel_mps2=accel_mps2,
            distance_m=distance_m,
            rear_x_m=x - self.rear_overhang_m * cos_yaw,
            rear_y_m=y - self.rear_overhang_m * sin_yaw,
        )


def lead_car_path(config: LeadCarConfig, ego_x_m: float, ego_y_m: float, ego_yaw_rad: float,
                  rear_overhang_m: float) -> LeadCarPath:
    """The lead car's line: ``gap`` ahead of and ``lateral_offset`` left of the ego's start."""
    cos_yaw, sin_yaw = math.cos(ego_yaw_rad), math.sin(ego_yaw_rad)
    return LeadCarPath(
        start_x_m=ego_x_m + config.gap_m * cos_yaw - config.lateral_offset_m * sin_yaw,
        start_y_m=ego_y_m + config.gap_m * sin_yaw + config.lateral_offset_m * cos_yaw,
        yaw_rad=ego_yaw_rad,
        rear_overhang_m=rear_overhang_m,
    )


def advance_lead_car(config: LeadCarConfig, path: LeadCarPath, state: LeadCarState,
                     dt_s: float) -> LeadCarState:
    """The lead car ``dt_s`` later: constant acceleration over the step (exact), stopping
    (not reversing) when the speed would fall below zero."""
    accel = config.accel_at(state.t_s)
    speed = state.speed_mps + accel * dt_s
    if speed >= 0.0:
        distance = state.distance_m + 0.5 * (state.speed_mps + speed) * dt_s
    else:
        # It stops within the step, after v^2 / (2 |a|).
        distance = state.distance_m + state.speed_mps**2 / (2.0 * -accel)
        accel = -state.speed_mps / dt_s
        speed = 0.0
    return path.state(state.t_s + dt_s, distance, speed, accel)
