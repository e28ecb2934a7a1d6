"""The stage cost the trajectory-tracking MPCs share (its weights: :mod:`tracker.config`).

Stage ``k`` of the nonlinear MPC (:mod:`tracker.mpc.nmpc_problem`) and of the LTV-MPC
(:mod:`tracker.mpc.ltv_qp`) costs ``dt * sum_i w_i e_i^2`` over

- the input terms of ``u_k`` against ``u_{k-1}`` (the applied command for ``k = 0``):
  acceleration, steering (less the reference point's steady-turn steering, where the
  tracker feeds it forward), and their rates ``(u_k - u_{k-1}) / dt``;
- the tracking terms of node ``k + 1`` against reference point ``k``: the cross-track error
  measured from the reference point's tangent,
  ``e_y = -sin(psi_r) (x - x_r) + cos(psi_r) (y - y_r)``, the heading error ``psi - psi_r``
  (the path yaw unwrapped along the horizon, so no wrapping is needed) and the speed error
  ``v_x - v_r`` (Rawlings, Mayne, Diehl, "Model Predictive Control: Theory, Computation,
  and Design", 2nd ed., Nob Hill 2017, sec. 1.3's tracking cost on these errors).

Written with plain arithmetic and CasADi's ``sin``/``cos``, so each solver builds its cost
from the same expressions (the real-time iteration takes the errors themselves as the
residuals of its Gauss-Newton Hessian).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import casadi as ca

from tracker.config import TrackerWeights
from tracker.mpc.fallback import INPUT

Term = tuple[float, Any]
"""``(weight per second, error)``: the error is a CasADi expression."""


def input_terms(u: Any, previous: Any, dt_s: float, weights: TrackerWeights,
                steer_reference: Any = None) -> list[Term]:
    """Acceleration, steering (less ``steer_reference`` if given) and their rates."""
    accel, steer = INPUT["accel_mps2"], INPUT["steer_rad"]
    accel_rate = (u[accel] - previous[accel]) / dt_s
    steer_rate = (u[steer] - previous[steer]) / dt_s
    steer_error = u[steer] if steer_reference is None else u[steer] - steer_reference
    return [
        (weights.accel, u[accel]),
        (weights.steer, steer_error),
        (weights.accel_rate, accel_rate),
        (weights.steer_rate, steer_rate),
    ]


def tracking_terms(x: Any, index: Mapping[str, int], ref_x_m: Any, ref_y_m: Any,
                   ref_yaw_rad: Any, ref_speed_mps: Any, weights: TrackerWeights) -> list[Term]:
    """Cross-track, heading and speed error of the state ``x`` against a reference point."""
    dx = x[index["x_m"]] - ref_x_m
    dy = x[index["y_m"]] - ref_y_m
    cte = -ca.sin(ref_yaw_rad) * dx + ca.cos(ref_yaw_rad) * dy
    heading_error = x[index["yaw_rad"]] - ref_yaw_rad
    speed_error = x[index["vx_mps"]] - ref_speed_mps
    return [(weights.cte, cte), (weights.heading, heading_error), (weights.speed, speed_error)]


def weighted_squares(terms: list[Term]) -> Any:
    """``w_0 e_0^2 + w_1 e_1^2 + ...`` for ``(w, e)`` pairs, summed left to right."""
    total = None
    for weight, error in terms:
        term = weight * error**2
        total = term if total is None else total + term
    return total
