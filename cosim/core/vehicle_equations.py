"""The equations every vehicle model of cosim shares: the axle slip angles, the saturating
axle force and the RK4 step.

The controllers' bicycle models (:mod:`tracker.models`), the filters' process model
(:mod:`estimation`) and the identification's fits (:mod:`cosim.identification`) each build
their own model, but from these: one statement of each equation, written with plain
arithmetic so that it takes CasADi symbols (for exact Jacobians) as well as floats.

Slip angles of a single-track (bicycle) model with small angles, front road-wheel angle
``delta``, CoG lateral velocity ``v_y`` and yaw rate ``r`` in the vehicle frame (ISO 8855),
CoG to axle distances ``l_f``, ``l_r`` (Rajamani, "Vehicle Dynamics and Control", 2nd ed.,
Springer 2012, sec. 2.3, eq. 2.23 and 2.24)::

    alpha_f = delta - (v_y + l_f r) / v_x                                 (D1)
    alpha_r = -(v_y - l_r r) / v_x                                        (D2)

An axle's lateral force: linear in its slip angle with the cornering stiffness ``C`` (D3), or
that linear force with a smooth limit at the friction force ``mu F_z`` of the axle's load
(D3'), the same stiffness at small slip; beyond the linear range a tyre gives less than (D3)
says and at most ``mu F_z`` (Pacejka, "Tyre and Vehicle Dynamics", 3rd ed., Elsevier 2012,
ch. 1 and 4: the Magic Formula's curve, of which (D3') keeps the slope at zero and the
peak)::

    F_y = C alpha                                                         (D3)
    F_y = mu F_z tanh(C alpha / (mu F_z))                                 (D3')

The classical fourth-order Runge-Kutta step of ``x' = f(x)`` over ``h`` (Hairer, Norsett,
Wanner, "Solving Ordinary Differential Equations I", 2nd ed., Springer 1993, sec. II.1)::

    k1 = f(x),  k2 = f(x + h/2 k1),  k3 = f(x + h/2 k2),  k4 = f(x + h k3)
    x+ = x + h/6 (k1 + 2 k2 + 2 k3 + k4)

with the stage times ``t, t + h/2, t + h/2, t + h`` for a time-varying ``f(x, t)``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import casadi as ca

Value = Any
"""A float, a numpy array or a CasADi expression: these equations take any of them."""


def axle_slip_angles(vy_mps: Value, yaw_rate_radps: Value, steer_rad: Value,
                     speed_mps: Value, cog_front_m: Value, cog_rear_m: Value
                     ) -> tuple[Value, Value]:
    """Front and rear axle slip angles (D1)-(D2) [rad]; ``speed_mps`` is the forward speed
    the model divides by (a model guards it at low speed as it sees fit)."""
    alpha_front = steer_rad - (vy_mps + cog_front_m * yaw_rate_radps) / speed_mps
    alpha_rear = -(vy_mps - cog_rear_m * yaw_rate_radps) / speed_mps
    return alpha_front, alpha_rear


def saturating_axle_force(linear_force_n: Value, limit_n: Value) -> Value:
    """(D3'): the linear tyre's force ``linear_force_n`` (``C alpha``, (D3)) held smoothly
    within the friction force ``limit_n`` (``mu F_z``) [N]; floats or CasADi symbols."""
    return limit_n * ca.tanh(linear_force_n / limit_n)


def rk4_step(f: Callable[[Value], Value], x: Value, h: Value) -> Value:
    """One classical RK4 step of ``x' = f(x)`` over ``h``."""
    k1 = f(x)
    k2 = f(x + 0.5 * h * k1)
    k3 = f(x + 0.5 * h * k2)
    k4 = f(x + h * k3)
    return x + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


def rk4_step_in_time(f: Callable[[Value, Value], Value], x: Value, t: Value,
                     h: Value) -> Value:
    """One classical RK4 step of ``x' = f(x, t)`` from ``t`` over ``h``."""
    k1 = f(x, t)
    k2 = f(x + 0.5 * h * k1, t + 0.5 * h)
    k3 = f(x + 0.5 * h * k2, t + 0.5 * h)
    k4 = f(x + h * k3, t + h)
    return x + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
