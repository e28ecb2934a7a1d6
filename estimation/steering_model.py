"""The steering actuator as the filters believe it: the road-wheel angle driven by the command.

The plant's actuator (:mod:`cosim.plant.steering`) turns the road wheels toward the command
``u`` through a first-order lag of time constant ``tau`` with a rate limit ``r_max``, the
command clipped to ``delta_max``. Once the filter is told the commands (the controller's,
from the time they act on the actuator as the software believes it:
:meth:`estimation.fusion.KalmanFusion.command`), its steering states follow the same law::

    u_c = clip(u, -delta_max, delta_max)
    v   = (u_c - delta) / tau                             (the lag's rate)       (S1)
    v_l = v / (1 + (v / r_max)^8)^(1/8)                   (a smooth rate limit)  (S2)
    delta' = v_l + w_delta,   delta_r' = (v_l - delta_r) / tau_r + w_dr         (S3)

The angle follows the lag itself (a command's step moves it at once, as the plant's lag
does); the rate state ``delta_r`` relaxes to the lag's rate with the short time constant
``tau_r`` (:data:`RATE_RELAXATION_S`), so it stays the road wheels' rate for whoever reads
it. The rate limit (S2) is within 9 % of the hard limit at ``|v| = r_max`` and within 1 %
beyond ``1.6 r_max``, and smooth for the EKF's Jacobian. Without a command (a filter nobody
tells them, before the first one) the angle is the integrated random walk of
:mod:`estimation.process_model` (``delta' = delta_r + w_delta``, ``delta_r' = w_dr``):
written as ``delta' = delta_r + c (v_l - delta_r)``, ``delta_r' = c (v_l - delta_r) /
tau_r`` with ``c`` 1 or 0, the same numbers as that model when ``c = 0``.

Why: at the start of a run the filter's prior is drawn a few centimetres and degrees off, and
the controller steers against that error at once, reversing within a tenth of a second. A
random walk on the rate keeps the rate it had through the reversal, the steering sensor
disagrees by 2-3 cm rad, and the gate refused it in the first second of 27 of 40 runs
(gnss suite, lane change). The numbers are the belief's (``tracker.model.*``, which the
filter shares with the controller): ``steer_time_constant_s``, ``max_steer_rate_radps``
and ``max_steer_rad``.

The road wheels are not rigidly held: each turns about its steering axis against the
steering's stiffness ``k`` (per wheel), and a wheel spinning at ``omega = v_x / R`` whose
axle the body rolls at ``p`` needs the gyroscopic moment ``I_s omega p`` about that axis
(``I_s`` its spin inertia; Gillespie, "Fundamentals of Vehicle Dynamics", 1992, ch. 8,
gyroscopic steering moments). The actuator's angle ``delta_a`` therefore leads the road
wheels' by the deflection::

    D = c omega p,   c = I_s / k,   delta = delta_a - D                        (S4)

The state is the road wheels' angle (what the tyres and the steering sensor see); the lag
(S1) acts on ``delta_a = delta + D`` and, with a command, ``delta' = delta_a' - D'`` with
``D' = c (v_x' p + v_x p') / R``. On the sedan (``c`` = 1.0 / 5700 s^2, the plant's servo
gain) a lane change's swerve rolls the body at 0.1-0.15 rad/s at 20 m/s: 1-1.5 mrad, one
to two of the steering sensor's sigmas, which the filter's steering, told the commands,
had held as its own error. ``c`` 0: rigid wheels, (S1)-(S3) as they were.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from cosim.core.vehicle_params import VehicleParams

RATE_RELAXATION_S = 0.01
"""``tau_r`` of (S3): how fast the rate state takes the actuator's rate [s]. Short against
the lag (0.05 s on the sedan), long enough for one RK4 sub-step of ``max_step_s``."""

MIN_TIME_CONSTANT_S = 0.01
"""The smallest lag (S1) divides by: a belief of 0 (no lag) is a lag this short."""

COMMAND_INPUTS: tuple[str, ...] = ("steer_command_rad", "commanded")
"""The process model's input vector: the steering command acting now, and 1 when there is
one (0: the rate is a random walk and the command is not read)."""


@dataclass(frozen=True)
class SteeringBelief:
    """The numbers of (S1)-(S3): the believed actuator lag, rate limit and angle limit."""

    time_constant_s: float = 0.05
    max_rate_radps: float = 0.8
    max_angle_rad: float = 0.5236
    gyro_deflection_s2: float = 0.0
    """``c = I_s / k`` of (S4): the road wheels' deflection per wheel spin rate times roll
    rate [rad / (rad/s)^2]; 0: rigid."""
    wheel_radius_m: float = 0.31
    """``R`` of (S4): the wheel spin rate is ``v_x / R``."""

    @classmethod
    def from_vehicle(cls, belief: VehicleParams,
                     compliance_radpnm: float = 0.0) -> SteeringBelief:
        """The belief's actuator, its wheels deflecting ``compliance_radpnm`` (``1 / k``) per
        newton metre about the steering axis."""
        return cls(time_constant_s=float(belief.steer_time_constant_s),
                   max_rate_radps=float(belief.max_steer_rate_radps),
                   max_angle_rad=float(belief.max_steer_rad),
                   gyro_deflection_s2=float(belief.wheel_inertia_kgm2 * compliance_radpnm),
                   wheel_radius_m=float(belief.wheel_radius_m))


def command_input(command_rad: float | None) -> np.ndarray:
    """The input vector (:data:`COMMAND_INPUTS`) for a command, or for none."""
    if command_rad is None:
        return np.zeros(len(COMMAND_INPUTS))
    return np.array([float(command_rad), 1.0])


def gyro_deflection(vx_mps: ca.SX, roll_rate_radps: ca.SX,
                    steering: SteeringBelief) -> ca.SX:
    """``D`` of (S4): how far the actuator's angle leads the road wheels' [rad]."""
    return steering.gyro_deflection_s2 * vx_mps / steering.wheel_radius_m * roll_rate_radps


def gyro_deflection_rate(vx_mps: ca.SX, vx_change_mps2: ca.SX, roll_rate_radps: ca.SX,
                         roll_accel_radps2: ca.SX, steering: SteeringBelief) -> ca.SX:
    """``D' = c (v_x' p + v_x p') / R`` of (S4), from the speed's and the roll rate's
    derivatives."""
    return steering.gyro_deflection_s2 / steering.wheel_radius_m * (
        vx_change_mps2 * roll_rate_radps + vx_mps * roll_accel_radps2)


def steering_derivatives(steer_rad: ca.SX, steer_rate_radps: ca.SX, command: ca.SX,
                         steering: SteeringBelief, deflection: ca.SX = 0.0,
                         deflection_rate: ca.SX = 0.0) -> tuple[ca.SX, ca.SX]:
    """``delta'`` and ``delta_r'`` without noise: (S1)-(S4) with a command
    (``command[1] = 1``; ``deflection`` and its rate are ``D`` and ``D'`` of (S4)), the
    integrated random walk without (module docstring)."""
    target = ca.fmin(ca.fmax(command[0], -steering.max_angle_rad), steering.max_angle_rad)
    lag_rate = ((target - steer_rad - deflection)
                / ca.fmax(steering.time_constant_s, MIN_TIME_CONSTANT_S))
    ratio2 = (lag_rate / steering.max_rate_radps) ** 2
    ratio8 = (ratio2 * ratio2) ** 2
    # (1 + ratio^8)^(1/8) as three square roots: the same function, cheaper in C than pow.
    limited = lag_rate / ca.sqrt(ca.sqrt(ca.sqrt(1.0 + ratio8)))
    pull = command[1] * (limited - steer_rate_radps)
    return steer_rate_radps + pull - command[1] * deflection_rate, pull / RATE_RELAXATION_S
