"""A noisy centre line smoothed: the curvature is the road's, not the survey's."""

from __future__ import annotations

import numpy as np
import pytest

from tracker.paths.centre_line import estimate_noise_m, smooth_centre_line
from tracker.paths.reference_path import ReferencePath


def _noisy_circle(radius_m: float, spacing_m: float, noise_m: float) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(4)
    theta = np.arange(0.0, 2.0 * np.pi - 1e-9, spacing_m / radius_m)
    return (radius_m * np.cos(theta) + rng.normal(0.0, noise_m, theta.size),
            radius_m * np.sin(theta) + rng.normal(0.0, noise_m, theta.size))


def _radius_range(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    path = ReferencePath(x, y, 1.0, closed=True)
    curvature = path.sample(np.arange(0.0, path.length_m, 0.5))["curvature_1pm"]
    return 1.0 / np.abs(curvature).max(), 1.0 / np.abs(curvature).min()


@pytest.mark.parametrize("noise_m", [0.02, 0.05])
def test_the_noise_is_estimated_and_the_curvature_recovered(noise_m: float) -> None:
    x, y = _noisy_circle(30.0, 2.0, noise_m)
    assert estimate_noise_m(x, y, closed=True) == pytest.approx(noise_m, rel=0.3)
    raw_low, raw_high = _radius_range(x, y)
    line = smooth_centre_line(x, y, closed=True)
    low, high = _radius_range(line.x_m, line.y_m)
    assert 30.0 * 0.85 < low and high < 30.0 * 1.15  # the road's radius, within 15 %
    assert raw_low < 30.0 * 0.7  # what an interpolating spline would read from the points


def test_a_clean_line_is_taken_as_it_is() -> None:
    x, y = _noisy_circle(30.0, 2.0, 0.0)
    line = smooth_centre_line(x, y, closed=True)
    np.testing.assert_array_equal(line.x_m, x)
