"""The ISO 3888-1 double lane change: cone gates sized from the car's width, and a path.

ISO 3888-1:2018, "Passenger cars - Test track for a severe lane-change manoeuvre - Part 1:
Double lane-change", lays out six sections (lengths 15, 30, 25, 25, 15, 15 m); sections 1,
3, 5 and 6 are lanes bounded by cones, 2 and 4 are the free transitions between them. The
lane widths follow from the vehicle width ``w``:

==========  ========  ===================  ==========================================
section     length    lane width           lateral position
==========  ========  ===================  ==========================================
1 (entry)   15 m      1.1 w + 0.25 m       centred on the approach line, y = 0
2           30 m      (free)
3 (offset)  25 m      1.2 w + 0.25 m       near edge 3.5 m left of the entry centre line
4           25 m      (free)
5 (exit)    15 m      1.3 w + 0.25 m       right edge in line with section 1's right edge
6 (exit)    15 m      1.3 w + 0.25 m       as section 5
==========  ========  ===================  ==========================================

The lateral placement is the reading of the standard's drawing that Project Chrono's
double-lane-change demo uses (lane 3's centre ``1.2 w / 2 + 0.125 + 3.5`` m left of lane 1's
centre; lanes 1, 5 and 6 share their right-hand cone line). The reference path is the
centre line of the lanes, joined across sections 2 and 4 by cosine blends (continuous
heading and curvature at the joins of a half-cosine: curvature is zero at both ends).
A gate is hit when a corner of the car's body is beyond one of its cone lines while that
corner is within the section's length.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tracker.paths.shapes import STEP_M, Shape

SECTION_LENGTHS_M = (15.0, 30.0, 25.0, 25.0, 15.0, 15.0)
"""Lengths of sections 1-6 along the track [m]."""
LANE_OFFSET_M = 3.5
"""Lateral gap from lane 1's centre line to lane 3's near (right) cone line [m]."""
CONE_CLEARANCE_M = 0.25
"""What each lane width adds to its multiple of the vehicle width [m]."""


@dataclass(frozen=True)
class Gate:
    """One coned lane: its section number, extent along x and cone lines (world frame)."""

    section: int
    x_start_m: float
    x_end_m: float
    y_right_m: float
    y_left_m: float

    @property
    def centre_m(self) -> float:
        return 0.5 * (self.y_right_m + self.y_left_m)

    def cones(self, spacing_m: float = 5.0) -> np.ndarray:
        """Cone positions (rows ``x, y``) along both cone lines, ends included."""
        n = max(2, int(round((self.x_end_m - self.x_start_m) / spacing_m)) + 1)
        x = np.linspace(self.x_start_m, self.x_end_m, n)
        return np.vstack((np.column_stack((x, np.full(n, self.y_right_m))),
                          np.column_stack((x, np.full(n, self.y_left_m)))))


def gates(vehicle_width_m: float, start_x_m: float) -> tuple[Gate, ...]:
    """The four coned lanes (sections 1, 3, 5, 6) for a car ``vehicle_width_m`` wide, the
    first starting at ``start_x_m`` on the x axis (the approach runs along y = 0)."""
    edges = start_x_m + np.concatenate(([0.0], np.cumsum(SECTION_LENGTHS_M)))
    width_1 = 1.1 * vehicle_width_m + CONE_CLEARANCE_M
    width_3 = 1.2 * vehicle_width_m + CONE_CLEARANCE_M
    width_5 = 1.3 * vehicle_width_m + CONE_CLEARANCE_M
    right_1 = -width_1 / 2.0
    right_3 = LANE_OFFSET_M
    return (
        Gate(1, edges[0], edges[1], right_1, right_1 + width_1),
        Gate(3, edges[2], edges[3], right_3, right_3 + width_3),
        Gate(5, edges[4], edges[5], right_1, right_1 + width_5),
        Gate(6, edges[5], edges[6], right_1, right_1 + width_5),
    )


def _blend(x: np.ndarray, x0: float, x1: float, y0: float, y1: float) -> np.ndarray:
    u = np.clip((x - x0) / (x1 - x0), 0.0, 1.0)
    return (y1 - y0) * (0.5 - 0.5 * np.cos(np.pi * u))


def centre_line(course: tuple[Gate, ...], length_m: float) -> Shape:
    """The path through the lanes' centres, straight before the first and after the last."""
    first, offset, exit_5 = course[0], course[1], course[2]
    x = np.arange(0.0, max(length_m, exit_5.x_end_m + 50.0) + STEP_M, STEP_M)
    y = (first.centre_m
         + _blend(x, first.x_end_m, offset.x_start_m, first.centre_m, offset.centre_m)
         + _blend(x, offset.x_end_m, exit_5.x_start_m, offset.centre_m, exit_5.centre_m))
    return Shape(x, y, False)


def corners(x_m: float, y_m: float, yaw_rad: float, front_m: float, rear_m: float,
            half_width_m: float) -> np.ndarray:
    """The body's four corners (rows ``x, y``) for a CoG at ``(x_m, y_m)`` heading ``yaw``,
    ``front_m`` to the front bumper and ``rear_m`` to the rear one."""
    c, s = np.cos(yaw_rad), np.sin(yaw_rad)
    local = np.array([[front_m, half_width_m], [front_m, -half_width_m],
                      [-rear_m, half_width_m], [-rear_m, -half_width_m]])
    return np.column_stack((x_m + c * local[:, 0] - s * local[:, 1],
                            y_m + s * local[:, 0] + c * local[:, 1]))


def gate_hit(gate: Gate, body_corners: np.ndarray) -> bool:
    """Whether any corner inside the gate's length is beyond one of its cone lines."""
    x, y = body_corners[:, 0], body_corners[:, 1]
    inside = (x >= gate.x_start_m) & (x <= gate.x_end_m)
    return bool(np.any(inside & ((y < gate.y_right_m) | (y > gate.y_left_m))))
