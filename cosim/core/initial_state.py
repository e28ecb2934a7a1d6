"""Where and how fast the car starts."""

from __future__ import annotations

from dataclasses import dataclass

from cosim.core.config_fields import setting


@dataclass(frozen=True)
class InitialState:
    """Initial pose and speed of the car's centre of gravity (world frame, ENU)."""

    x_m: float = setting(0.0, low=-1e5, high=1e5)
    y_m: float = setting(0.0, low=-1e5, high=1e5)
    yaw_rad: float = setting(0.0, low=-3.1416, high=3.1416)
    speed_mps: float = setting(15.0, low=0.0, high=80.0, doc="forward speed")
    speed_from_profile: bool = setting(
        False,
        doc="start at the reference speed profile's speed where the car starts (its "
        "projection on the path), instead of speed_mps: a circuit whose first bend is "
        "tight is entered at a speed it can be driven at")
