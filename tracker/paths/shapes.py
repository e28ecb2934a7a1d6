"""Built-in path shapes as point lists: each starts at the origin heading along +x.

Shapes are laid out by integrating a curvature profile (:func:`from_curvature`), so heading
and position are continuous and the curvature changes along clothoid-like ramps where a
shape joins straight and curved pieces (a step in curvature is a step in steering that no
tracker can follow). The exceptions are closed shapes that are exact curves (the circle)
and the slalom (a tapered sine through its cones).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

STEP_M = 0.5
"""Spacing of the points handed to the spline [m]."""


@dataclass(frozen=True)
class Shape:
    """Points of a path, in driving order, and whether it closes on itself."""

    x_m: np.ndarray
    y_m: np.ndarray
    closed: bool


def cumulative_trapezoid(y: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The running integral of ``y`` over ``x`` by the trapezoid rule, from 0 at the
    first point: ``I_k = sum_{j<k} (x_{j+1} - x_j) (y_j + y_{j+1}) / 2``."""
    return np.concatenate(([0.0], np.cumsum(np.diff(x) * (y[1:] + y[:-1]) / 2.0)))


def from_curvature(s_m: np.ndarray, curvature_1pm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Integrate ``yaw' = kappa``, ``x' = cos yaw``, ``y' = sin yaw`` from the origin."""
    yaw = cumulative_trapezoid(curvature_1pm, s_m)
    return (cumulative_trapezoid(np.cos(yaw), s_m),
            cumulative_trapezoid(np.sin(yaw), s_m))


def _ramp(s_m: np.ndarray, start_m: float, length_m: float) -> np.ndarray:
    """0 before ``start_m``, 1 after ``start_m + length_m``, a cosine blend between."""
    u = np.clip((s_m - start_m) / length_m, 0.0, 1.0)
    return 0.5 - 0.5 * np.cos(np.pi * u)


def straight(length_m: float) -> Shape:
    x = np.arange(0.0, length_m + STEP_M, STEP_M)
    return Shape(x, np.zeros_like(x), False)


def circle(radius_m: float) -> Shape:
    """A closed circle of ``radius_m``, counter-clockwise, centre at ``(0, radius_m)``."""
    n = max(64, int(2.0 * np.pi * radius_m / STEP_M))
    theta = np.arange(n) * 2.0 * np.pi / n
    return Shape(radius_m * np.sin(theta), radius_m * (1.0 - np.cos(theta)), True)


def figure_eight(radius_m: float, transition_m: float = 10.0) -> Shape:
    """A closed figure eight: two 270-degree arcs of ``radius_m``, a left and a right one,
    joined by straights that cross at the origin at right angles (each straight is tangent
    to both circles, so its half-length is ``radius_m``). Curvature ramps over
    ``transition_m`` centred on each join; the small gap that the ramps leave at the end of
    the lap is spread linearly along it. The figure is turned so that it starts at the
    origin heading along +x (the first straight runs along +x)."""
    r = radius_m
    arc = 1.5 * np.pi * r
    joins = np.cumsum([r, arc, 2.0 * r, arc])
    length = joins[-1] + r
    s = np.arange(0.0, length, STEP_M)
    k = 1.0 / r
    half = transition_m / 2.0
    kappa = (k * _ramp(s, joins[0] - half, transition_m)
             - k * _ramp(s, joins[1] - half, transition_m)
             - k * _ramp(s, joins[2] - half, transition_m)
             + k * _ramp(s, joins[3] - half, transition_m))
    yaw = np.pi / 4.0 + cumulative_trapezoid(kappa, s)
    x = cumulative_trapezoid(np.cos(yaw), s)
    y = cumulative_trapezoid(np.sin(yaw), s)
    # Close the loop: the end should come back to the start.
    end_x = x[-1] + np.cos(yaw[-1]) * (length - s[-1])
    end_y = y[-1] + np.sin(yaw[-1]) * (length - s[-1])
    x -= end_x * s / length
    y -= end_y * s / length
    rot = -np.pi / 4.0
    return Shape(np.cos(rot) * x - np.sin(rot) * y, np.sin(rot) * x + np.cos(rot) * y, True)


def s_curve(radius_m: float, arc_deg: float, approach_m: float, length_m: float,
            transition_m: float = 15.0) -> Shape:
    """Straight, a left arc of ``arc_deg`` at ``radius_m``, a right arc of the same, straight;
    curvature ramps over ``transition_m`` (clothoids) between the pieces."""
    arc_m = np.radians(arc_deg) * radius_m
    s = np.arange(0.0, length_m + STEP_M, STEP_M)
    k = 1.0 / radius_m
    first = approach_m
    second = first + transition_m + arc_m
    third = second + 2.0 * transition_m + arc_m
    kappa = (k * _ramp(s, first, transition_m)
             - 2.0 * k * _ramp(s, second, 2.0 * transition_m)
             + k * _ramp(s, third, transition_m))
    x, y = from_curvature(s, kappa)
    return Shape(x, y, False)


def slalom(spacing_m: float, cones: int, amplitude_m: float, approach_m: float,
           length_m: float) -> Shape:
    """Weave through ``cones`` cones ``spacing_m`` apart on the x axis, the first at
    ``approach_m``: ``y = A w sin(pi (x - x0) / spacing)``, with ``w`` rising over the first
    gap and falling over the last, so the heading is continuous in and out."""
    x = np.arange(0.0, length_m + STEP_M, STEP_M)
    x0, x_end = approach_m - spacing_m / 2.0, approach_m + (cones - 0.5) * spacing_m
    taper = _ramp(x, x0, spacing_m) * (1.0 - _ramp(x, x_end - spacing_m, spacing_m))
    y = amplitude_m * taper * np.sin(np.pi * (x - x0) / spacing_m)
    return Shape(x, y, False)


def slalom_cones(spacing_m: float, cones: int, approach_m: float) -> np.ndarray:
    """Cone positions of :func:`slalom` (rows ``x, y``)."""
    x = approach_m + spacing_m * np.arange(cones)
    return np.column_stack((x, np.zeros_like(x)))
