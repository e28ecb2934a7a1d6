"""The low-level actuation layer: from the tracker's acceleration demand to wheel torques.

Where each conversion happens in a run:

1. The tracker outputs a :class:`~cosim.core.records.Command` (``accel_mps2``, ``steer_rad``).
2. :class:`AccelToTorque` (this module; in a real car, the powertrain/brake controller)
   turns ``accel_mps2`` into a total drive torque or a total brake torque at the wheels,
   using the controller's *belief* about the car (a :class:`VehicleParams`): effective mass
   including the wheels' rotational inertia, wheel radius, drag area and rolling
   resistance, and clips it to the believed torque and power limits. If the belief is wrong
   (the real car is heavier, draggier, ...), the car does not get the acceleration the
   tracker asked for: that is a genuine model mismatch, as on a real vehicle.
3. The plant (:class:`cosim.plant.car.MujocoPlant`) receives the :class:`ActuatorCommand`, clips
   it to the *true* limits, splits drive torque over the driven wheels and brake torque over
   all four, and passes the steering angle through its steering-actuator model.
4. Optionally (``plant.slip_control.enabled``, off by default so that a wrong belief shows
   as wheel spin), the car's own traction control and ABS
   (:mod:`cosim.plant.slip_control`) cut the drive or brake torque every physics step when
   a wheel's slip ratio, from the four wheel speeds, exceeds ``slip_max``.

Longitudinal model used for the inversion (Gillespie, Fundamentals of Vehicle Dynamics,
1992, ch. 2 "Acceleration performance", with the wheels' rotational inertia lumped into
the mass, and ch. 4 "Road loads"):

    (m + 4 I_w / R^2) a = F_x - 1/2 rho C_d A v^2 - C_rr m g,   F_x = T / R
"""

from __future__ import annotations

import math

from cosim.core.physical_constants import AIR_DENSITY_KGPM3, GRAVITY_MPS2
from cosim.core.records import ActuatorCommand, Command
from cosim.core.vehicle_params import VehicleParams

ROLLING_SPEED_SCALE_MPS = 0.1
"""Speed over which rolling resistance fades in, ``tanh(v / scale)``: a smooth stand-in for
its sign so there is no chatter at standstill [m/s]."""

MIN_POWER_SPEED_MPS = 0.5
"""Below this speed the power limit is evaluated at this speed (it would be infinite at
standstill; the torque limit governs there) [m/s]."""


def resistance_constants(params: VehicleParams) -> dict[str, float]:
    """The products of :func:`resistance_force_n` that do not depend on the speed, as it
    forms them: drag ``(1/2 rho) C_d A`` times ``v|v|``, rolling ``(C_rr m) g`` times
    ``tanh(v / v_0)`` (for the compiled physics step, :mod:`cosim.plant.compiled_steps`)."""
    return {
        "drag_coefficient": 0.5 * AIR_DENSITY_KGPM3 * params.drag_area_m2,
        "rolling_force_n": params.rolling_resistance * params.mass_kg * GRAVITY_MPS2,
        "rolling_speed_scale_mps": ROLLING_SPEED_SCALE_MPS,
    }


def resistance_force_n(params: VehicleParams, speed_mps: float) -> float:
    """Aerodynamic drag plus rolling resistance opposing forward motion at ``speed_mps`` [N].

    ``1/2 rho C_d A v|v| + C_rr m g tanh(v / 0.1 m/s)`` (Gillespie ch. 4; a constant
    rolling-resistance coefficient).
    """
    drag = 0.5 * AIR_DENSITY_KGPM3 * params.drag_area_m2 * speed_mps * abs(speed_mps)
    rolling = (
        params.rolling_resistance
        * params.mass_kg
        * GRAVITY_MPS2
        * math.tanh(speed_mps / ROLLING_SPEED_SCALE_MPS)
    )
    return drag + rolling


def effective_mass_kg(params: VehicleParams) -> float:
    """Mass plus the translational equivalent of the four wheels' spin inertia, I_w / R^2."""
    return params.mass_kg + 4.0 * params.wheel_inertia_kgm2 / params.wheel_radius_m**2


class AccelToTorque:
    """Turns an acceleration demand into drive or brake torque with a belief about the car.

    ``belief`` is the controller's model of the car (``tracker.model``), not the plant's
    truth. Steering passes through unchanged (the plant clips it to the true limit).
    """

    def __init__(self, belief: VehicleParams) -> None:
        self.belief = belief
        self._mass_eff_kg = effective_mass_kg(belief)

    def convert(self, command: Command, speed_mps: float) -> ActuatorCommand:
        """Wheel torques for ``command`` at the (estimated) forward speed ``speed_mps``.

        Required tractive force ``F = m_eff a + F_resist(v)``; if ``F >= 0`` it is delivered
        as drive torque ``F R`` clipped to ``max_drive_torque_nm`` and to the power limit
        ``P R / v``; otherwise as brake torque ``-F R`` clipped to ``max_brake_torque_nm``.
        """
        if not math.isfinite(speed_mps):
            raise ValueError(f"speed_mps = {speed_mps!r}: expected a finite number")
        belief = self.belief
        force_n = self._mass_eff_kg * command.accel_mps2 + resistance_force_n(belief, speed_mps)
        torque_nm = force_n * belief.wheel_radius_m
        if torque_nm >= 0.0:
            power_limited_nm = (
                belief.max_drive_power_w
                * belief.wheel_radius_m
                / max(abs(speed_mps), MIN_POWER_SPEED_MPS)
            )
            drive_nm = min(torque_nm, belief.max_drive_torque_nm, power_limited_nm)
            brake_nm = 0.0
        else:
            drive_nm = 0.0
            brake_nm = min(-torque_nm, belief.max_brake_torque_nm)
        return ActuatorCommand(
            t_s=command.t_s,
            drive_torque_nm=drive_nm,
            brake_torque_nm=brake_nm,
            steer_rad=command.steer_rad,
        )
