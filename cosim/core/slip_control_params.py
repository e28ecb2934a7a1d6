"""Settings of the car's own wheel-slip control: ``plant.slip_control``.

A record of the plant's configuration (the controller is part of the car, like the traction
control and ABS of a production car's brake ECU); the control itself is
:mod:`cosim.plant.slip_control`. Off by default, so a low-level torque mismatch (a wrong
belief about the mass, a wet road) stays visible as wheel spin.
"""

from __future__ import annotations

from dataclasses import dataclass

from cosim.core.config_fields import setting


@dataclass(frozen=True)
class SlipControlParams:
    """Traction control (drive torque) and anti-lock braking (brake torque) by wheel slip."""

    enabled: bool = setting(
        False,
        doc="limit the wheels' longitudinal slip by cutting drive torque (traction control) "
        "and brake torque (anti-lock); off: the torques pass unchanged",
    )
    slip_max: float = setting(
        0.05,
        low=0.005,
        high=0.5,
        doc="slip ratio above which the torque is cut, (omega R - v) / v; below the Magic "
        "Formula tyre's peak (about 0.1 mu for the default tyre) down to friction 0.5 [-]",
    )
    cut_gain: float = setting(
        20.0,
        low=0.1,
        high=1000.0,
        doc="share of the torque removed per unit of slip above slip_max (20: all of it "
        "at 0.05 above) [-]",
    )
    recovery_rate: float = setting(
        2.0,
        low=0.01,
        high=1000.0,
        doc="how fast the torque share comes back once the slip is below slip_max [1/s]",
    )
    speed_floor_mps: float = setting(
        1.0,
        low=0.01,
        high=20.0,
        doc="the reference speed in the slip ratio's denominator is at least this (a "
        "standing start) [m/s]",
    )
