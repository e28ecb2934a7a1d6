"""Reference points over the horizon: the path spline and a cubic fitted in the vehicle frame."""

from __future__ import annotations

import numpy as np
import pytest

from cosim.core.exceptions import ConfigError
from tracker.mpc.horizon_reference import horizon_reference
from tracker.paths.reference_path import ReferencePath

SPEEDS_MPS = np.full(26, 20.0)
"""A horizon of 25 stages at 20 m/s: 25 m of preview at dt 0.05 s."""


def _arc(radius_m: float, angle_rad: float) -> ReferencePath:
    theta = np.linspace(0.0, angle_rad, 600)
    return ReferencePath(radius_m * np.sin(theta), radius_m * (1.0 - np.cos(theta)), 20.0)


def test_on_a_straight_line_both_kinds_agree_exactly() -> None:
    x = np.linspace(0.0, 200.0, 201)
    path = ReferencePath(x, 0.5 * x, 20.0)  # a line at atan(0.5)
    spline = horizon_reference("spline", path, 50.0, 26.0, 0.3, SPEEDS_MPS, 0.05)
    cubic = horizon_reference("cubic-polynomial", path, 50.0, 26.0, 0.3, SPEEDS_MPS, 0.05)
    for a, b in ((spline.x_m, cubic.x_m), (spline.y_m, cubic.y_m),
                 (spline.yaw_rad, cubic.yaw_rad)):
        np.testing.assert_allclose(a, b, atol=1e-6)
    np.testing.assert_allclose(cubic.curvature_1pm, 0.0, atol=1e-9)
    # Stage k lies k * 1 m further along the line than the car's projection.
    s0 = path.project(50.0, 26.0).s_m
    along = np.hypot(spline.x_m - path.point(s0).x_m, spline.y_m - path.point(s0).y_m)
    np.testing.assert_allclose(along, np.arange(1, 26) * 1.0, atol=1e-6)


def test_on_a_gentle_arc_the_cubic_is_close_to_the_spline() -> None:
    """80 m radius, the lane change's tightest bend: 25 m of arc is nearly a cubic."""
    path = _arc(80.0, 2.0)
    spline = horizon_reference("spline", path, 30.0, 6.0, 0.4, SPEEDS_MPS, 0.05)
    cubic = horizon_reference("cubic-polynomial", path, 30.0, 6.0, 0.4, SPEEDS_MPS, 0.05)
    gap = np.hypot(spline.x_m - cubic.x_m, spline.y_m - cubic.y_m)
    assert np.max(gap) < 0.01
    np.testing.assert_allclose(cubic.yaw_rad, spline.yaw_rad, atol=2e-3)
    np.testing.assert_allclose(cubic.curvature_1pm, 1.0 / 80.0, rtol=0.05)


def test_headings_are_rebased_near_the_car_yaw() -> None:
    path = _arc(80.0, 2.0)
    turned = horizon_reference("spline", path, 30.0, 6.0, 0.4 + 2.0 * np.pi, SPEEDS_MPS, 0.05)
    plain = horizon_reference("spline", path, 30.0, 6.0, 0.4, SPEEDS_MPS, 0.05)
    np.testing.assert_allclose(turned.yaw_rad - plain.yaw_rad, 2.0 * np.pi)


def test_where_the_path_folds_back_the_cubic_gives_way_to_the_spline() -> None:
    """A 6 m radius U-turn inside the window has no y(x) in the vehicle frame."""
    path = _arc(6.0, 3.0)
    cubic = horizon_reference("cubic-polynomial", path, 0.0, 0.0, 0.0, SPEEDS_MPS, 0.02)
    spline = horizon_reference("spline", path, 0.0, 0.0, 0.0, SPEEDS_MPS, 0.02)
    np.testing.assert_array_equal(cubic.x_m, spline.x_m)


def test_an_unknown_kind_is_refused() -> None:
    with pytest.raises(ConfigError, match="tracker.reference = 'bezier'"):
        horizon_reference("bezier", _arc(80.0, 1.0), 0.0, 0.0, 0.0, SPEEDS_MPS, 0.05)
