"""A reference path parametrised by arc length, with projection of points onto it.

The path is a cubic spline x(s), y(s) through densely sampled points
(:mod:`tracker.paths.cubic_spline`). Projection
finds the arc length of the nearest point: a coarse search over a dense table (all of it, or
a window around a known arc length), then Newton steps on the spline. The Newton steps
evaluate the spline's cubic pieces from its coefficients in plain floats (Horner), a
microsecond each instead of the tens a vectorised scipy call costs on one point; the
runner projects the car 100 times per simulated second. The signed lateral error is
positive when the point lies left of the path (ISO 8855 / ENU convention).

A closed path (a circuit) is a periodic spline: arc lengths wrap modulo the lap length,
so a tracker can read the path ahead across the start line. The reference speed is part of
the reference: a :class:`tracker.paths.speed_profile.SpeedProfile` gives it at an arc
length and a time (constant, a function of arc length such as a circuit's friction-limited
profile, or a function of time such as stop-and-go); ``speed_mps`` is its top speed.
"""

from __future__ import annotations

import bisect
import functools
import math
from dataclasses import dataclass

import numpy as np

from cosim.core.exceptions import ConfigError
from tracker.paths.compiled_path import CompiledPath, path_library
from tracker.paths.cubic_spline import CubicSpline
from tracker.paths.speed_profile import ConstantSpeed, SpeedProfile


@dataclass(frozen=True)
class PathPoint:
    """The path at one arc length."""

    s_m: float
    x_m: float
    y_m: float
    yaw_rad: float
    curvature_1pm: float


@dataclass(frozen=True)
class Projection:
    """Where a point sits relative to the path."""

    s_m: float
    lateral_error_m: float
    """Signed distance to the path, positive when the point is left of it."""
    path_yaw_rad: float
    curvature_1pm: float


def wrap_angle(angle_rad: np.ndarray | float) -> np.ndarray | float:
    """Wrap to (-pi, pi]: ``pi - ((pi - angle) mod 2 pi)``. One float is wrapped in plain
    floats (Python's remainder is numpy's, to the bit), an array by numpy."""
    if isinstance(angle_rad, float):
        return math.pi - (math.pi - angle_rad) % math.tau
    return np.pi - np.mod(np.pi - np.asarray(angle_rad), 2.0 * np.pi)


def path_curvature(dx: np.ndarray, dy: np.ndarray, ddx: np.ndarray,
                   ddy: np.ndarray) -> np.ndarray:
    """The signed curvature of a plane curve from its first and second derivatives,
    ``(x' y'' - y' x'') / (x'^2 + y'^2)^(3/2)`` (positive turning left)."""
    return (dx * ddy - dy * ddx) / (dx * dx + dy * dy) ** 1.5


class ReferencePath:
    """A planar path with a reference speed.

    Args:
      x_m, y_m: points along the path in the world frame, in driving order. For a closed
        path the last point must not repeat the first: the spline closes the loop itself.
      speed_mps: the reference speed along the whole path, or a speed profile.
      table_step_m: spacing of the projection table.
      closed: the path is a loop (periodic spline, arc lengths modulo the lap).
    """

    def __init__(
        self, x_m: np.ndarray, y_m: np.ndarray, speed_mps: float | SpeedProfile,
        table_step_m: float = 0.25, closed: bool = False,
    ) -> None:
        x_m = np.asarray(x_m, dtype=float)
        y_m = np.asarray(y_m, dtype=float)
        if x_m.shape != y_m.shape or x_m.ndim != 1 or x_m.size < 4:
            raise ConfigError("reference path: expected matching 1-D x and y of >= 4 points")
        if closed:
            x_m, y_m = np.append(x_m, x_m[0]), np.append(y_m, y_m[0])
        seg = np.hypot(np.diff(x_m), np.diff(y_m))
        if np.any(seg <= 0.0):
            raise ConfigError("reference path: expected distinct consecutive points")
        s = np.concatenate(([0.0], np.cumsum(seg)))
        boundary = "periodic" if closed else "not-a-knot"
        self._x = CubicSpline(s, x_m, boundary)
        self._y = CubicSpline(s, y_m, boundary)
        self.closed = closed
        self.length_m = float(s[-1])
        self.speed_profile: SpeedProfile = (
            speed_mps if isinstance(speed_mps, SpeedProfile) else ConstantSpeed(speed_mps))
        self.speed_mps = self.speed_profile.top_speed_mps
        """The profile's top speed (the constant reference speed of most paths) [m/s]."""
        self._table_step_m = float(table_step_m)
        self._table_s = np.arange(0.0, self.length_m, table_step_m)
        self._table_x = self._x(self._table_s)
        self._table_y = self._y(self._table_s)
        self._knots_m: list[float] = s.tolist()
        # Per piece i, the coefficients (a, b, c, d) of x(s) = a h^3 + b h^2 + c h + d,
        # h = s - s_i, for x and y, highest power first.
        self._coefficients = np.vstack((self._x.c, self._y.c)).T.copy()
        self._knots = s
        self._pieces: list[tuple[float, ...]] = self._coefficients.tolist()

    def wrap(self, s_m: np.ndarray | float) -> np.ndarray:
        """Arc lengths on the path: modulo the lap on a closed path, else clamped to it."""
        s = np.asarray(s_m, dtype=float)
        if self.closed:
            return np.mod(s, self.length_m)
        return np.clip(s, 0.0, self.length_m)

    def speed_ref(self, s_m: np.ndarray | float, t_s: np.ndarray | float) -> np.ndarray:
        """The reference speed at arc lengths ``s_m`` and times ``t_s`` [m/s]."""
        profile = self.speed_profile
        s = self.wrap(s_m) if profile.reads_arc_length else np.asarray(s_m, dtype=float)
        return profile.speed_mps(s, np.asarray(t_s, dtype=float))

    def speed_ref_at(self, s_m: float, t_s: float) -> float:
        """:meth:`speed_ref` at one arc length and one time, as a float: the arc length
        wrapped or clamped as :meth:`wrap` does, in plain floats (Python's ``%`` is numpy's
        ``mod`` for floats, ``min``/``max`` its ``clip``)."""
        s = float(s_m)
        s = s % self.length_m if self.closed else min(max(s, 0.0), self.length_m)
        return self.speed_profile.speed_at(s, float(t_s))

    def point(self, s_m: float) -> PathPoint:
        """The path at arc length ``s_m`` (clamped to the path, or wrapped when closed)."""
        s = float(self.wrap(s_m))
        dx, dy = float(self._x(s, 1)), float(self._y(s, 1))
        ddx, ddy = float(self._x(s, 2)), float(self._y(s, 2))
        curvature = (dx * ddy - dy * ddx) / (dx * dx + dy * dy) ** 1.5
        return PathPoint(s, float(self._x(s)), float(self._y(s)), float(np.arctan2(dy, dx)),
                         float(curvature))

    def sample(self, s_m: np.ndarray) -> dict[str, np.ndarray]:
        """Vectorised :meth:`point`: arrays ``x_m``, ``y_m``, ``yaw_rad``, ``curvature_1pm``.

        The cubic pieces are evaluated by Horner's rule on arrays (one search for the
        pieces, no spline object called): a horizon of 25 points in about 20 us."""
        s = self.wrap(s_m)
        i = np.searchsorted(self._knots, s, side="right") - 1  # the piece, within the path
        np.minimum(np.maximum(i, 0, out=i), self._coefficients.shape[0] - 1, out=i)
        h = s - self._knots[i]
        ax, bx, cx, d_x, ay, by, cy, d_y = self._coefficients[i].T
        dx, dy = (3.0 * ax * h + 2.0 * bx) * h + cx, (3.0 * ay * h + 2.0 * by) * h + cy
        ddx, ddy = 6.0 * ax * h + 2.0 * bx, 6.0 * ay * h + 2.0 * by
        return {
            "s_m": s,
            "x_m": ((ax * h + bx) * h + cx) * h + d_x,
            "y_m": ((ay * h + by) * h + cy) * h + d_y,
            "yaw_rad": np.arctan2(dy, dx),
            "curvature_1pm": path_curvature(dx, dy, ddx, ddy),
        }

    def _evaluate(self, s_m: float) -> tuple[float, float, float, float, float, float]:
        """``x, y`` and their first and second derivatives in arc length at ``s_m``
        (within ``[0, length_m]``), from the cubic piece that holds it."""
        i = min(max(bisect.bisect_right(self._knots_m, s_m) - 1, 0), len(self._pieces) - 1)
        h = s_m - self._knots_m[i]
        ax, bx, cx, dx, ay, by, cy, dy = self._pieces[i]
        return (
            ((ax * h + bx) * h + cx) * h + dx,
            ((ay * h + by) * h + cy) * h + dy,
            (3.0 * ax * h + 2.0 * bx) * h + cx,
            (3.0 * ay * h + 2.0 * by) * h + cy,
            6.0 * ax * h + 2.0 * bx,
            6.0 * ay * h + 2.0 * by,
        )

    def project(self, x_m: float, y_m: float, near_s_m: float | None = None,
                window_m: float = 25.0) -> Projection:
        """Project a point onto the path: nearest table point, then Newton on the spline.

        With ``near_s_m`` (e.g. the previous projection of a moving car), only the table
        within ``window_m`` of it is searched, so a path that passes near itself (a loop)
        cannot make the point jump to its other branch, and the search costs the window,
        not the path's length. Computed in C where a compiler works
        (:mod:`tracker.paths.compiled_path`: the same numbers to the bit, a few
        microseconds instead of some 25), else by :meth:`project_in_python`.
        """
        projector = self._compiled
        # A near_s_m that is not finite: Python raises on it as it always did.
        if projector is not None and (near_s_m is None or math.isfinite(near_s_m)):
            return Projection(*projector(float(x_m), float(y_m), near_s_m, float(window_m)))
        return self.project_in_python(x_m, y_m, near_s_m, window_m)

    def prepare_projection(self) -> None:
        """Load the compiled projection and horizon now (on a machine's first run, build
        them: a fraction of a second), e.g. before a run's clock starts; else the first
        :meth:`project` does."""
        _ = self._compiled  # a cached property: computed once, kept

    @functools.cached_property
    def _compiled(self) -> CompiledPath | None:
        """This path's projection and horizon in C (None without a working compiler)."""
        library = path_library()
        if library is None:
            return None
        return CompiledPath(library, self._table_s, self._table_x, self._table_y, self._knots,
                            self._coefficients, self.length_m, self._table_step_m, self.closed)

    def compiled_horizon(self, x_m: float, y_m: float, speeds_mps: np.ndarray, dt_s: float
                         ) -> tuple[Projection, np.ndarray] | None:
        """:meth:`tracker.paths.compiled_path.CompiledPath.horizon` of this path (the
        projection and the spline at a horizon's stages); None without a working
        compiler, or where a subclass projects in its own way (its :meth:`project`
        serves)."""
        compiled = self._compiled
        if compiled is None or type(self).project is not ReferencePath.project:
            return None
        projection, stages = compiled.horizon(float(x_m), float(y_m), speeds_mps,
                                              float(dt_s))
        return Projection(*projection), stages

    def project_in_python(self, x_m: float, y_m: float, near_s_m: float | None = None,
                          window_m: float = 25.0) -> Projection:
        """:meth:`project` in numpy and plain floats (the reference the C is held to)."""
        table_s, table_x, table_y = self._table_s, self._table_x, self._table_y
        first = 0
        if near_s_m is not None and self.closed:
            # On a circuit the window wraps around the start line.
            step, count = self._table_step_m, self._table_s.size
            centre, half = int((near_s_m % self.length_m) / step), int(window_m / step) + 1
            index = np.arange(centre - half, centre + half + 1) % count
            table_s, table_x, table_y = table_s[index], table_x[index], table_y[index]
        elif near_s_m is not None:
            step = self._table_step_m
            first = max(int((near_s_m - window_m) / step), 0)
            last = max(int(math.ceil((near_s_m + window_m) / step)) + 1, first + 1)
            table_s, table_x = table_s[first:last], table_x[first:last]
            table_y = table_y[first:last]
            if not table_s.size:  # beyond the path's end: search all of it
                first, table_s = 0, self._table_s
                table_x, table_y = self._table_x, self._table_y
        i = int(np.argmin((table_x - x_m) ** 2 + (table_y - y_m) ** 2))
        s = float(table_s[i])
        length = self.length_m
        for _ in range(3):
            px, py, dx, dy, ddx, ddy = self._evaluate(s)
            # d/ds of 0.5*|p(s) - q|^2 and its derivative.
            grad = (px - x_m) * dx + (py - y_m) * dy
            hess = dx * dx + dy * dy + (px - x_m) * ddx + (py - y_m) * ddy
            if hess <= 1e-9:
                break
            s = s - grad / hess
            s = s % length if self.closed else min(max(s, 0.0), length)
        px, py, dx, dy, ddx, ddy = self._evaluate(s)
        yaw = math.atan2(dy, dx)
        curvature = (dx * ddy - dy * ddx) / (dx * dx + dy * dy) ** 1.5
        lateral = -math.sin(yaw) * (x_m - px) + math.cos(yaw) * (y_m - py)
        return Projection(s, lateral, yaw, curvature)
