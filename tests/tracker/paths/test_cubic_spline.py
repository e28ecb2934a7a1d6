"""The reference path's own cubic spline is scipy's ``CubicSpline`` with the same ends."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.interpolate import CubicSpline as ScipySpline

from tracker.paths.cubic_spline import CubicSpline, solve_tridiagonal


@pytest.mark.parametrize("boundary", ["not-a-knot", "periodic"])
@pytest.mark.parametrize("count", [4, 5, 31, 2000])
def test_the_spline_is_scipys_to_round_off(boundary: str, count: int) -> None:
    rng = np.random.default_rng(count)
    knots = np.concatenate(([0.0], np.cumsum(rng.uniform(0.2, 3.0, count - 1))))
    values = 10.0 * rng.normal(size=count)
    if boundary == "periodic":
        values[-1] = values[0]
    ours, scipys = CubicSpline(knots, values, boundary), ScipySpline(knots, values,
                                                                     bc_type=boundary)
    s = np.linspace(knots[0], knots[-1], 3001)
    for nu in (0, 1, 2):
        reference = scipys(s, nu)
        assert np.max(np.abs(ours(s, nu) - reference)) <= 1e-13 * np.max(np.abs(reference))
    assert np.max(np.abs(ours.c - scipys.c)) <= 1e-12 * np.max(np.abs(scipys.c))


def test_bad_knots_are_refused() -> None:
    with pytest.raises(ValueError, match="strictly increasing"):
        CubicSpline(np.array([0.0, 1.0, 1.0, 2.0]), np.zeros(4), "not-a-knot")
    with pytest.raises(ValueError, match="last value must equal its first"):
        CubicSpline(np.arange(5.0), np.arange(5.0), "periodic")


@pytest.mark.parametrize("size", [1, 2, 3, 8, 300])
def test_the_tridiagonal_solve_is_numpys_dense_one_also_where_it_must_pivot(size: int) -> None:
    rng = np.random.default_rng(size)
    lower, upper = rng.normal(size=size - 1), rng.normal(size=size - 1)
    diagonal = rng.normal(size=size)
    diagonal[0] = 1e-14 * (size > 1) + (size == 1)  # without a row swap: ruinous growth
    rhs = rng.normal(size=size)
    dense = np.diag(diagonal) + np.diag(lower, -1) + np.diag(upper, 1)
    expected = np.linalg.solve(dense, rhs)
    solved = solve_tridiagonal(lower, diagonal, upper, rhs)
    assert np.max(np.abs(solved - expected)) <= 1e-10 * np.max(np.abs(expected))
