"""The interpolating cubic spline of a reference path: coordinates as cubics in arc length.

Through knots ``s_0 < ... < s_{n-1}`` with values ``v_i``, the spline is one cubic per
interval, fixed by its values and its slopes ``d_i`` at both ends (Hermite form, de Boor,
"A Practical Guide to Splines", rev. ed. 2001, ch. IV). With ``h_i = s_{i+1} - s_i`` and
the chord slopes ``m_i = (v_{i+1} - v_i) / h_i``, the second derivative is continuous at
each interior knot when

    h_i d_{i-1} + 2 (h_{i-1} + h_i) d_i + h_{i-1} d_{i+1} = 3 (h_i m_{i-1} + h_{i-1} m_i),

a tridiagonal system closed by the ends:

* ``not-a-knot`` (an open path): the third derivative is continuous at ``s_1`` and
  ``s_{n-2}`` too (the first two and the last two pieces are one cubic each), which gives
  ``h_1 d_0 + (h_0 + h_1) d_1 = ((h_0 + 2 (h_0 + h_1)) h_1 m_0 + h_0^2 m_1) / (h_0 + h_1)``
  and its mirror at the end;
* ``periodic`` (a circuit, ``v_{n-1} = v_0``): the knots wrap, ``d_{n-1} = d_0``, and the
  system is cyclic; its two corner entries are handled by the Sherman-Morrison formula
  (Press et al., "Numerical Recipes", 3rd ed., section 2.7.2) around two banded solves.

The tridiagonal systems are solved by Gaussian elimination with partial pivoting between
neighbouring rows (:func:`solve_tridiagonal`). The same spline as
``scipy.interpolate.CubicSpline`` with these end conditions (tested to round-off), without
importing scipy at all: ``scipy.interpolate`` costs more than half a second of every start
for this one spline, and even ``scipy.linalg`` (for ``solve_banded``) a sixth of one.

Each piece is kept as ``a h^3 + b h^2 + c h + d`` in the local ``h = s - s_i``
(:attr:`CubicSpline.c`: rows ``a, b, c, d``, highest power first) with
``a = (d_i + d_{i+1} - 2 m_i) / h_i^2``, ``b = (3 m_i - 2 d_i - d_{i+1}) / h_i``,
``c = d_i`` and ``d = v_i``.
"""

from __future__ import annotations

import numpy as np

BOUNDARIES: tuple[str, ...] = ("not-a-knot", "periodic")


class CubicSpline:
    """The cubic spline through ``(knots, values)`` (see the module docstring).

    ``knots`` strictly increasing, at least 4; with ``periodic`` the last value must equal
    the first. Called with arc lengths inside ``[s_0, s_{n-1}]`` (the path wraps or clamps
    them first); outside, the end pieces are extended.
    """

    def __init__(self, knots: np.ndarray, values: np.ndarray, boundary: str) -> None:
        s = np.asarray(knots, dtype=float)
        v = np.asarray(values, dtype=float)
        if boundary not in BOUNDARIES:
            raise ValueError(f"boundary = {boundary!r}: expected one of {', '.join(BOUNDARIES)}")
        if s.ndim != 1 or s.shape != v.shape or s.size < 4 or np.any(np.diff(s) <= 0.0):
            raise ValueError("expected at least 4 strictly increasing knots and one value each")
        if boundary == "periodic" and v[-1] != v[0]:
            raise ValueError("a periodic spline's last value must equal its first")
        h = np.diff(s)
        m = np.diff(v) / h
        slopes = _periodic_slopes(h, m) if boundary == "periodic" else _not_a_knot_slopes(h, m)
        start, end = slopes[:-1], slopes[1:]
        self.knots = s
        self.c = np.vstack(((start + end - 2.0 * m) / h**2,
                            (3.0 * m - 2.0 * start - end) / h, start, v[:-1]))
        """The pieces' coefficients, shape ``(4, n - 1)``: ``a, b, c, d`` per piece."""

    def __call__(self, s_m: np.ndarray | float, nu: int = 0) -> np.ndarray:
        """The spline (``nu = 0``), its first or second derivative at ``s_m``."""
        s = np.asarray(s_m, dtype=float)
        i = np.clip(np.searchsorted(self.knots, s, side="right") - 1, 0, self.c.shape[1] - 1)
        h = s - self.knots[i]
        a, b, c, d = self.c[:, i]
        if nu == 0:
            return ((a * h + b) * h + c) * h + d
        if nu == 1:
            return (3.0 * a * h + 2.0 * b) * h + c
        if nu == 2:
            return 6.0 * a * h + 2.0 * b
        raise ValueError(f"nu = {nu}: expected 0, 1 or 2")


def _continuity_rows(h: np.ndarray, m: np.ndarray) -> tuple[np.ndarray, ...]:
    """The interior rows ``i = 1..n-2``: sub-, main and super-diagonal and right side."""
    return h[1:], 2.0 * (h[:-1] + h[1:]), h[:-1], 3.0 * (h[1:] * m[:-1] + h[:-1] * m[1:])


def solve_tridiagonal(lower: np.ndarray, diagonal: np.ndarray, upper: np.ndarray,
                      rhs: np.ndarray) -> np.ndarray:
    """``x`` with ``T x = rhs``, ``T`` tridiagonal: sub-diagonal ``lower`` (``n - 1``),
    ``diagonal`` (``n``), super-diagonal ``upper`` (``n - 1``).

    Gaussian elimination with partial pivoting, which for a tridiagonal matrix only ever
    compares a row with the next (Golub, Van Loan, "Matrix Computations", 4th ed., 2013,
    section 4.3.5; LAPACK's ``dgtsv`` does the same): where the next row's entry below the
    pivot is the larger, the two rows swap, and the swapped row fills a second
    super-diagonal; then back substitution. ``O(n)``, on Python floats (a spline of a few
    thousand knots solves in milliseconds). Raises ``ZeroDivisionError`` when ``T`` is
    singular.
    """
    d = [float(v) for v in diagonal]
    n = len(d)
    du = [float(v) for v in upper] + [0.0]
    dl = [float(v) for v in lower]
    b = [float(v) for v in rhs]
    du2 = [0.0] * n
    for i in range(n - 1):
        if abs(d[i]) >= abs(dl[i]):  # keep the pivot: eliminate row i + 1's first entry
            factor = dl[i] / d[i]
            d[i + 1] -= factor * du[i]
            b[i + 1] -= factor * b[i]
        else:  # swap rows i and i + 1, then eliminate
            factor = d[i] / dl[i]
            d[i], next_diagonal = dl[i], d[i + 1]
            d[i + 1] = du[i] - factor * next_diagonal
            du2[i] = du[i + 1]
            du[i + 1] = -factor * du2[i]
            du[i] = next_diagonal
            b[i], b[i + 1] = b[i + 1], b[i] - factor * b[i + 1]
    x = [0.0] * n
    x[-1] = b[-1] / d[-1]
    if n > 1:
        x[-2] = (b[-2] - du[-2] * x[-1]) / d[-2]
    for i in range(n - 3, -1, -1):
        x[i] = (b[i] - du[i] * x[i + 1] - du2[i] * x[i + 2]) / d[i]
    return np.array(x)


def _not_a_knot_slopes(h: np.ndarray, m: np.ndarray) -> np.ndarray:
    n = h.size + 1
    diagonal, upper, lower = np.empty(n), np.empty(n - 1), np.empty(n - 1)
    rhs = np.empty(n)
    interior_lower, interior_diagonal, interior_upper, right = _continuity_rows(h, m)
    diagonal[1:-1] = interior_diagonal
    upper[1:] = interior_upper
    lower[:-1] = interior_lower
    rhs[1:-1] = right
    first = h[0] + h[1]
    diagonal[0], upper[0] = h[1], first
    rhs[0] = ((h[0] + 2.0 * first) * h[1] * m[0] + h[0] ** 2 * m[1]) / first
    last = h[-1] + h[-2]
    diagonal[-1], lower[-1] = h[-2], last
    rhs[-1] = (h[-1] ** 2 * m[-2] + (2.0 * last + h[-1]) * h[-2] * m[-1]) / last
    return solve_tridiagonal(lower, diagonal, upper, rhs)


def _periodic_slopes(h: np.ndarray, m: np.ndarray) -> np.ndarray:
    """Slopes of the cyclic system (unknowns ``d_0 .. d_{n-2}``, ``d_{n-1} = d_0``)."""
    k = h.size  # unknowns; row i couples d_{i-1}, d_i, d_{i+1} modulo k
    before, after = np.roll(h, 1), h  # h_{i-1} and h_i of row i
    before_m, after_m = np.roll(m, 1), m
    diagonal = 2.0 * (before + after)
    lower = after  # coefficient of d_{i-1} in row i
    upper = before  # coefficient of d_{i+1} in row i
    rhs = 3.0 * (after * before_m + before * after_m)
    # A = T + u w' with T tridiagonal: A[0, k-1] = lower[0], A[k-1, 0] = upper[k-1].
    gamma = -diagonal[0]
    main = diagonal.copy()
    main[0] -= gamma
    main[-1] -= lower[0] * upper[-1] / gamma
    u = np.zeros(k)
    u[0], u[-1] = gamma, upper[-1]
    y = solve_tridiagonal(lower[1:], main, upper[:-1], rhs)
    z = solve_tridiagonal(lower[1:], main, upper[:-1], u)
    w_y = y[0] + lower[0] * y[-1] / gamma
    w_z = z[0] + lower[0] * z[-1] / gamma
    slopes = y - (w_y / (1.0 + w_z)) * z
    return np.append(slopes, slopes[0])
