"""A measured centre line made smooth enough to read curvature from.

A circuit's centre line comes as points 1-5 m apart with centimetres to decimetres of
noise (surveyed or traced from imagery). An interpolating spline goes through every point,
so its second derivative, the curvature that sets the speed profile and the steering
feed-forward, carries the noise amplified by ``1 / ds^2``: 5 cm at 2 m spacing is
0.05 / 4 ~ 0.01 1/m of false curvature, a 100 m bend where the road is straight.

:func:`smooth_centre_line` fits a smoothing cubic spline instead (FITPACK's parametric
spline, Dierckx, "Curve and Surface Fitting with Splines", Oxford 1993, ch. 9, through
:func:`scipy.interpolate.splprep`; periodic for a closed circuit) whose residual is
bounded by the noise: ``sum |p_i - s(u_i)|^2 <= s = 2 m sigma^2`` for ``m`` points. The
noise ``sigma`` is estimated from the data: third differences of the points cancel a
path's position, heading and curvature, so what remains is noise (variance ``20 sigma^2``
for independent noise of ``sigma`` per coordinate, ``1 + 9 + 9 + 1``), taken robustly as
the median absolute deviation (``sigma = 1.4826 MAD``, Huber, "Robust Statistics", 1981).
The fit is sampled every ``step_m`` of arc length. A line whose noise is below
:data:`CLEAN_NOISE_M` is returned as it is.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

MAD_TO_SIGMA = 1.4826
"""Standard deviation over median absolute deviation of a normal distribution."""

THIRD_DIFFERENCE_GAIN = np.sqrt(20.0)
"""Standard deviation of a third difference of independent unit noise."""

MIN_NOISE_M = 1e-3
"""The noise assumed at least (the points' rounding): a smoothing spline with ``s = 0``
interpolates and keeps every wiggle of the input."""

CLEAN_NOISE_M = 5e-3
"""Below this estimated noise a centre line is taken as it is (a drawn or generated line
rounded to millimetres): the points are returned unchanged, so the path interpolates them."""


@dataclass(frozen=True)
class SmoothedLine:
    """The smoothed centre line, sampled along its arc length."""

    x_m: np.ndarray
    y_m: np.ndarray
    noise_m: float
    """The estimated noise of the input points, per coordinate [m]."""


def estimate_noise_m(x_m: np.ndarray, y_m: np.ndarray, closed: bool) -> float:
    """The points' noise per coordinate from the MAD of their third differences (module
    docstring); at least :data:`MIN_NOISE_M`."""
    points = np.column_stack((x_m, y_m))
    if closed:
        points = np.vstack((points, points[:3]))
    third = np.diff(points, n=3, axis=0).ravel()
    if third.size < 4:
        return MIN_NOISE_M
    mad = np.median(np.abs(third - np.median(third)))
    return max(MIN_NOISE_M, float(MAD_TO_SIGMA * mad / THIRD_DIFFERENCE_GAIN))


def smooth_centre_line(x_m: np.ndarray, y_m: np.ndarray, closed: bool,
                       step_m: float = 1.0) -> SmoothedLine:
    """A smoothing spline through ``x_m, y_m`` (in driving order; a closed circuit's last
    point does not repeat its first), sampled every ``step_m`` of arc length from the
    first point on (the first sample is the fit at the first point)."""
    from scipy.interpolate import splev, splprep  # here: heavy, and for track files only

    x = np.asarray(x_m, dtype=float)
    y = np.asarray(y_m, dtype=float)
    noise = estimate_noise_m(x, y, closed)
    if noise < CLEAN_NOISE_M:
        return SmoothedLine(x.copy(), y.copy(), noise)
    if closed:
        x, y = np.append(x, x[0]), np.append(y, y[0])
    chord = np.concatenate(([0.0], np.cumsum(np.hypot(np.diff(x), np.diff(y)))))
    tck, _ = splprep([x, y], u=chord, s=2.0 * x.size * noise**2, per=int(closed), k=3,
                     quiet=1)
    # Arc length of the fit, tabulated finely, then sampled evenly.
    fine_u = np.linspace(0.0, chord[-1], max(8 * x.size, 2000))
    fx, fy = splev(fine_u, tck)
    arc = np.concatenate(([0.0], np.cumsum(np.hypot(np.diff(fx), np.diff(fy)))))
    count = max(int(round(arc[-1] / step_m)), 8)
    targets = np.linspace(0.0, arc[-1], count + 1)
    if closed:
        targets = targets[:-1]  # the loop closes itself: no repeated first point
    u = np.interp(targets, arc, fine_u)
    sx, sy = splev(u, tck)
    return SmoothedLine(np.asarray(sx), np.asarray(sy), noise)
