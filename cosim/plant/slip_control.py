"""Wheel-slip control of the car itself: traction control and anti-lock braking.

Why: the low-level layer (:mod:`cosim.plant.low_level`) turns the tracker's acceleration into
torque with the controller's *belief*. A car 30 % lighter than believed gets 43 % too much
drive torque; on a road of friction 0.7 its rear wheels spin, their lateral grip collapses
and the car turns round, whatever the tracker does (it did, in a run on the default
sedan). A production
car's brake ECU prevents that with traction control (TCS) and ABS; this is a minimal one,
run at the physics rate (a TCS runs at 100 Hz-1 kHz), on what such an ECU measures: the four
wheel speeds.

Slip ratio of wheel ``i`` (SAE J670 practical slip, positive when the wheel spins faster
than the road passes, Pacejka, "Tire and Vehicle Dynamics", 3rd ed., Butterworth-Heinemann
2012, sec. 1.2)::

    lambda_i = (omega_i R - v_ref) / max(v_ref, v_floor)                        (L1)

with the vehicle speed reference from the wheels themselves, as a classic TCS/ABS does
without a ground-speed sensor (Rajamani 2012, ch. 6 on ABS; the undriven wheels as the
reference in traction):

* driving: the mean of the undriven wheels' ``omega R``, or the slowest wheel when all
  four are driven;
* braking: the fastest wheel's ``omega R``.

The torque share ``k`` (one for the drive, one for the brakes) is cut at once and restored
slowly, the usual shape of a TCS torque intervention::

    k_target = clip(1 - cut_gain (lambda_worst - slip_max), 0, 1)             (L2)
    k <- k_target if k_target < k, else min(k + recovery dt, k_target)        (L3)

where ``lambda_worst`` is the largest slip of a driven wheel (drive) or the largest
locking ``-lambda`` of any wheel (brakes). The output torque is ``k`` times the demand.
Per-wheel brake modulation is left out: one share for all four brakes.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from cosim.core.slip_control_params import SlipControlParams


@dataclass(frozen=True)
class SlipLimited:
    """Torques after the slip control, and the shares it left of the demand."""

    drive_torque_nm: float
    brake_torque_nm: float
    drive_share: float
    brake_share: float


class SlipLimiter:
    """(L1)-(L3) for one car.

    Args:
      params: ``plant.slip_control``.
      wheel_radius_m: the car's rolling radius R.
      driven: for each wheel (in the order the spins are passed), whether it is driven.
    """

    def __init__(self, params: SlipControlParams, wheel_radius_m: float,
                 driven: Sequence[bool]) -> None:
        self.params = params
        self._radius_m = float(wheel_radius_m)
        self._driven = tuple(bool(d) for d in driven)
        self._undriven = tuple(not d for d in self._driven)
        self.reset()

    def reset(self) -> None:
        """Full torque, no intervention."""
        self._drive_share = 1.0
        self._brake_share = 1.0

    def _share(self, share: float, worst_slip: float, dt_s: float) -> float:
        p = self.params
        target = min(max(1.0 - p.cut_gain * (worst_slip - p.slip_max), 0.0), 1.0)  # (L2)
        if target < share:  # (L3)
            return target
        return min(share + p.recovery_rate * dt_s, target)

    def limit(self, drive_torque_nm: float, brake_torque_nm: float,
              wheel_spin_radps: Sequence[float], dt_s: float) -> SlipLimited:
        """The torques to apply this step, from the demand and the wheels' spins."""
        speeds = [omega * self._radius_m for omega in wheel_spin_radps]
        floor = self.params.speed_floor_mps
        undriven = [v for v, free in zip(speeds, self._undriven, strict=True) if free]
        traction_ref = sum(undriven) / len(undriven) if undriven else min(speeds)
        drive_slip = max((v - traction_ref) / max(traction_ref, floor)  # (L1)
                         for v, driven in zip(speeds, self._driven, strict=True) if driven)
        braking_ref = max(speeds)
        lock = max((braking_ref - v) / max(braking_ref, floor) for v in speeds)
        # A share recovers while its torque is not asked for (a slow inner wheel in a
        # bend must not hold back the next brake application).
        self._drive_share = self._share(self._drive_share,
                                        drive_slip if drive_torque_nm > 0.0 else 0.0, dt_s)
        self._brake_share = self._share(self._brake_share,
                                        lock if brake_torque_nm > 0.0 else 0.0, dt_s)
        return SlipLimited(drive_torque_nm * self._drive_share,
                           brake_torque_nm * self._brake_share,
                           self._drive_share, self._brake_share)
