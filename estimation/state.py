"""The Kalman filters' state: its names, their order, and the CasADi helpers over it.

The EKF (:mod:`estimation.ekf`) and the UKF (:mod:`estimation.ukf`) share every equation
here: the same CasADi functions, evaluated numerically (the EKF also uses their exact
Jacobians, the UKF only their values at its sigma points).

State (world frame ENU for the pose, vehicle frame ISO 8855 for the rates), named by
:data:`STATE_NAMES`:

===============================  ============================================================
``x_m``, ``y_m``                 position of the centre of gravity (CoG), world frame (a point
                                 of the body: it sways sideways when the body rolls)
``yaw_rad``                      heading of the vehicle x axis, CCW from world x, (-pi, pi]
``vx_mps``, ``vy_mps``           velocity of the CoG in the vehicle frame
``yaw_rate_radps``               yaw rate r
``ax_mps2``                      kinematic acceleration of the CoG along the vehicle x axis
                                 (what a gravity-compensated IMU measures; ``vx' = ax + r vy``)
``steer_rad``                    front road-wheel angle delta (mean of the two front wheels),
                                 positive to the left, as the ``steering`` sensor reports it
``roll_rad``                     body roll phi about the vehicle x axis (positive: left side
                                 up, as in a left turn)
``roll_rate_radps``              its rate p
``lateral_accel_residual_mps2``  lateral tyre force per unit mass that the tyre model does not
                                 explain (load transfer, camber, the tyre law's own error);
                                 the IMU's lateral acceleration observes it
``steer_rate_radps``             rate of ``steer_rad``: the steering actuator moves smoothly
                                 (a lag and a rate limit behind each command), so the angle
                                 keeps its rate between samples
``gyro_bias_radps``              bias of the IMU's yaw-rate channel
``ax_bias_mps2``                 bias of the IMU's longitudinal acceleration channel
``ay_bias_mps2``                 bias of the IMU's lateral acceleration channel
``rolling_radius_scale``         effective rolling radius of the freely rolling wheels over the
                                 believed one (tyre deflection, wear); dimensionless, ~1
``wheel_track_scale``            effective track of the freely rolling wheels (between their
                                 contact patches) over the believed one; dimensionless, ~1

The process model is :mod:`estimation.process_model`, the sensors' measurement models
are :mod:`estimation.measurement_models`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import casadi as ca
import numpy as np

VEHICLE_STATE_NAMES: tuple[str, ...] = (
    "x_m",
    "y_m",
    "yaw_rad",
    "vx_mps",
    "vy_mps",
    "yaw_rate_radps",
    "ax_mps2",
    "steer_rad",
    "roll_rad",
)
"""The filters' states that describe the car's motion (named as in VehicleState)."""

MODEL_STATE_NAMES: tuple[str, ...] = (
    "roll_rate_radps",
    "lateral_accel_residual_mps2",
    "steer_rate_radps",
)
"""States of the vehicle model that VehicleState does not carry: the roll rate, the error of
the tyre model, and the rate of the road-wheel angle."""

SENSOR_STATE_NAMES: tuple[str, ...] = (
    "gyro_bias_radps",
    "ax_bias_mps2",
    "ay_bias_mps2",
    "rolling_radius_scale",
    "wheel_track_scale",
)
"""States that describe the sensors: the biases of the gyro and of the longitudinal and
lateral accelerometers, the wheels' effective / believed rolling radius and track."""

STATE_NAMES: tuple[str, ...] = VEHICLE_STATE_NAMES + MODEL_STATE_NAMES + SENSOR_STATE_NAMES
"""Names of the filters' states, in the order of their mean and covariance."""

ANGLE_STATES: tuple[str, ...] = ("yaw_rad",)
"""States that are angles on the whole circle: wrapped to (-pi, pi] after every step."""


def wrap_angle(angle_rad: float | np.ndarray) -> float | np.ndarray:
    """Wrap an angle (or an array of angles) to (-pi, pi]."""
    if np.ndim(angle_rad) == 0 and -math.pi < float(angle_rad) <= math.pi:
        return float(angle_rad)  # the common case, without array overhead
    angle = np.asarray(angle_rad, dtype=float)
    wrapped = np.pi - np.mod(np.pi - angle, 2.0 * np.pi)
    # np.mod(-tiny, 2 pi) rounds to 2 pi, which would give -pi: move it to +pi.
    wrapped = np.where(wrapped <= -np.pi, wrapped + 2.0 * np.pi, wrapped)
    # Angles already in range are returned untouched (no rounding).
    wrapped = np.where((angle > -np.pi) & (angle <= np.pi), angle, wrapped)
    return float(wrapped) if np.ndim(wrapped) == 0 else wrapped


def wrap_angle_symbolic(angle: ca.SX | ca.MX) -> ca.SX | ca.MX:
    """:func:`wrap_angle` in CasADi: an angle in (-pi, pi] untouched, otherwise
    ``pi - mod(pi - angle, 2 pi)`` (numpy's ``mod``, the sign of the divisor), with -pi
    moved to +pi."""
    two_pi = 2.0 * math.pi
    shifted = math.pi - angle
    wrapped = math.pi - (shifted - two_pi * ca.floor(shifted / two_pi))
    wrapped = ca.if_else(wrapped <= -math.pi, wrapped + two_pi, wrapped)
    return ca.if_else(ca.logic_and(angle > -math.pi, angle <= math.pi), angle, wrapped)


def state_index(name: str) -> int:
    """Position of the state ``name`` in :data:`STATE_NAMES` (a clear error if unknown)."""
    if name not in STATE_NAMES:
        raise KeyError(f"unknown state {name!r}: expected one of {', '.join(STATE_NAMES)}")
    return STATE_NAMES.index(name)


def named_states(vector: ca.SX) -> dict[str, ca.SX]:
    """The entries of a symbolic state vector by name."""
    return {name: vector[i] for i, name in enumerate(STATE_NAMES)}


def stacked_states(values: Mapping[str, ca.SX | float]) -> ca.SX:
    """A symbolic state vector from one expression per state name."""
    missing = set(STATE_NAMES) - set(values)
    if missing:
        raise KeyError(f"missing state(s) {sorted(missing)}")
    return ca.vertcat(*[values[name] for name in STATE_NAMES])

