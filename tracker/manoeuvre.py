"""Open-loop manoeuvres: the ``manoeuvre:`` section of a scenario.

The steering input is a function of time only (no path feedback); the speed is held by a
proportional loop. These are the classic open-loop handling tests:

- ``steady-circle``: constant steering angle at constant speed (ISO 4138, constant
  steer-angle method) -> steady-state yaw rate, lateral acceleration, radius;
- ``step-steer``: zero steering, then a fast ramp to ``steer_rad`` at ``step_time_s``
  (ISO 7401 step input) -> yaw-rate response time and overshoot;
- ``ramp-steer``: steering growing at ``ramp_rate_radps`` from ``step_time_s`` on, at
  constant speed -> lateral acceleration up to saturation (about mu g).
"""

from __future__ import annotations

from dataclasses import dataclass

from cosim.core.config_fields import setting

MANOEUVRE_KINDS = ("steady-circle", "step-steer", "ramp-steer")


@dataclass(frozen=True)
class ManoeuvreConfig:
    """Steering profile and speed hold of the ``open-loop`` tracker."""

    kind: str = setting("steady-circle", choices=MANOEUVRE_KINDS)
    speed_mps: float = setting(10.0, low=0.0, high=80.0, doc="speed held by the speed loop")
    steer_rad: float = setting(0.05, low=-1.0, high=1.0, doc="road-wheel angle (final)")
    step_time_s: float = setting(1.0, low=0.0, high=3600.0, doc="start of the steering input")
    step_rate_radps: float = setting(
        0.7, low=0.01, high=100.0, doc="steering rate of the step's ramp"
    )
    ramp_rate_radps: float = setting(0.01, low=1e-4, high=10.0, doc="ramp-steer rate")
    speed_gain_1ps: float = setting(1.0, low=0.0, high=100.0, doc="accel per speed error")
    steady_window_s: float = setting(
        3.0, low=0.0, high=3600.0, doc="final window averaged for steady-state metrics"
    )

    def steer_at(self, t_s: float) -> float:
        """The commanded road-wheel angle at time ``t_s``."""
        elapsed = t_s - self.step_time_s
        if self.kind == "steady-circle":
            return self.steer_rad
        if elapsed <= 0.0:
            return 0.0
        rate = self.step_rate_radps if self.kind == "step-steer" else self.ramp_rate_radps
        magnitude = min(abs(self.steer_rad), rate * elapsed)
        return magnitude if self.steer_rad >= 0.0 else -magnitude
