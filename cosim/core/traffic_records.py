"""Records of traffic: another car's pose, and what the ego's range sensor reports.

They cross boundaries (plant -> sensing -> tracker -> log), so they live at the base of
``cosim/`` beside :mod:`cosim.core.records`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from cosim.core.records import flat_message


@dataclass(frozen=True)
class CarPose:
    """A traffic car at ``t_s``: the centre of its footprint in the world (ENU) and its motion."""

    name: str
    t_s: float
    x_m: float
    y_m: float
    yaw_rad: float
    speed_mps: float
    """Along its heading [m/s]."""
    accel_mps2: float
    """Along its heading [m/s^2]."""
    length_m: float
    width_m: float

    def to_message(self) -> dict[str, object]:
        return flat_message(self)


@dataclass(frozen=True)
class RangeReading:
    """One sample of the ego's forward range sensor (radar-like).

    ``target`` names the car it ranges to (the nearest car ahead in the ego's lane, inside
    the field of view and the maximum range); empty when there is none, and then the gap and
    the range rate are NaN.
    """

    t_s: float
    target: str
    gap_m: float
    """From the ego's front bumper to the target's rear, along the ego's heading [m]."""
    range_rate_mps: float
    """d gap / dt: the target's speed along the ego's heading minus the ego's [m/s]."""

    @property
    def has_target(self) -> bool:
        return bool(self.target) and math.isfinite(self.gap_m)

    def to_message(self) -> dict[str, object]:
        return flat_message(self)
