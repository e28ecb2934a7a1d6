"""Pure pursuit on cosim's preview points: the law inside the example Python FMUs.

Coulter, "Implementation of the pure pursuit path tracking algorithm", CMU-RI-TR-92-01,
1992: steer towards the point of the path at the look-ahead distance ``L_d`` on the arc of
curvature ``kappa = 2 y / L_d^2`` through it, ``steer = atan(wheelbase kappa) + K v^2 kappa``
(the second term the steady-state understeer of a car with understeer gradient ``K``,
Rajamani 2012, eq. 3.15, which the kinematic law lacks), with ``(x, y)``
the point in the frame of the rear axle (the centre of the car's turn: ISO 8855, x forward,
y left) and ``L_d = clip(L_min + t_la v, L_min, L_max)``. cosim gives the points in the
vehicle frame at the centre of gravity (``preview_x_m[i]``, ``preview_y_m[i]``,
docs/fmu.md), so ``x`` is moved back by the CoG-to-rear-axle distance ``l_r``; the point is
interpolated along the preview polyline. Speed: a proportional loop,
``accel = k_v (v_ref - v)``.
"""

from __future__ import annotations

import math
from typing import Any

PREVIEW_POINTS = 25
"""How many preview points the FMUs declare (2 m apart by default: 50 m ahead)."""


def lookahead_point(xs: list[float], ys: list[float],
                    distance_m: float) -> tuple[float, float]:
    """The first point of the polyline (the origin, then the preview points) at
    ``distance_m`` from the origin, interpolated on the segment that crosses that circle."""
    previous = (0.0, 0.0)
    for x, y in zip(xs, ys, strict=True):
        if math.hypot(x, y) >= distance_m:
            (x0, y0), d0 = previous, math.hypot(*previous)
            d1 = math.hypot(x, y)
            share = (distance_m - d0) / (d1 - d0) if d1 > d0 else 1.0
            return x0 + share * (x - x0), y0 + share * (y - y0)
        previous = (x, y)
    return previous


def steer_rad(xs: list[float], ys: list[float], speed_mps: float, wheelbase_m: float,
              cog_rear_m: float, understeer_radpmps2: float, lookahead_time_s: float,
              lookahead_min_m: float, lookahead_max_m: float) -> float:
    """The pure-pursuit steering angle (module docstring)."""
    distance = min(max(lookahead_min_m + lookahead_time_s * max(speed_mps, 0.0),
                       lookahead_min_m), lookahead_max_m)
    x, y = lookahead_point([x + cog_rear_m for x in xs], ys, distance)
    chord_sq = x * x + y * y
    if chord_sq < 1e-9:
        return 0.0
    kappa = 2.0 * y / chord_sq
    return math.atan(wheelbase_m * kappa) + understeer_radpmps2 * speed_mps**2 * kappa


def outputs(model: Any) -> tuple[float, float]:
    """``(steer_rad, accel_mps2)`` of an FMU class holding the inputs and parameters as
    attributes (``xs``, ``ys`` the preview points; the FMI 2 and FMI 3 classes share it)."""
    m = model
    steer = steer_rad(m.xs, m.ys, m.speed_mps, m.wheelbase_m, m.cog_rear_m,
                      m.understeer_radpmps2, m.lookahead_time_s, m.lookahead_min_m,
                      m.lookahead_max_m)
    return steer, m.speed_gain_1ps * (m.ref_speed_mps - m.speed_mps)
