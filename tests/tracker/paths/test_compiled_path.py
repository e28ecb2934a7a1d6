"""The path's C (:mod:`tracker.paths.compiled_path`): the projection gives the Python's
numbers to the bit, the horizon numpy's to rounding."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from tracker.mpc.horizon_reference import horizon_reference
from tracker.paths import shapes
from tracker.paths.compiled_path import path_library
from tracker.paths.double_lane_change import double_lane_change
from tracker.paths.generated_circuit import generated_circuit
from tracker.paths.reference_path import Projection, ReferencePath, wrap_angle

pytestmark = pytest.mark.skipif(path_library() is None, reason="no working C compiler")


def _same(a: Projection, b: Projection) -> bool:
    """Equal field by field, bit for bit, NaN equal to NaN."""
    return all(x == y or (math.isnan(x) and math.isnan(y)) for x, y in
               zip((a.s_m, a.lateral_error_m, a.path_yaw_rad, a.curvature_1pm),
                   (b.s_m, b.lateral_error_m, b.path_yaw_rad, b.curvature_1pm), strict=True))


def _paths() -> dict[str, ReferencePath]:
    track, eight = generated_circuit(7), shapes.figure_eight(30.0)
    return {"open": double_lane_change(20.0, length_m=200.0),
            "closed": ReferencePath(track.x_m, track.y_m, 15.0, closed=True),
            "crossing": ReferencePath(eight.x_m[::7], eight.y_m[::7], 10.0, table_step_m=1.3)}


@pytest.mark.parametrize("name", ["open", "closed", "crossing"])
def test_every_projection_is_the_pythons_to_the_bit(name: str) -> None:
    path = _paths()[name]
    rng = np.random.default_rng(11)
    s = rng.uniform(-20.0, path.length_m + 20.0, 400)
    points = path.sample(np.clip(s, 0.0, path.length_m))
    # Near the path and far from it, before its start and beyond its end.
    offsets = rng.normal(0.0, 1.0, (400, 2)) * rng.choice([0.1, 2.0, 30.0], (400, 1))
    x = points["x_m"] + offsets[:, 0] + np.where(s < 0.0, s, 0.0)
    y = points["y_m"] + offsets[:, 1]
    nears = [None, *rng.uniform(-40.0, path.length_m + 40.0, 3)]
    checked = 0
    for i in range(400):
        for near in (*nears, float(s[i])):
            for window in (25.0, 3.0):
                c = path.project(x[i], y[i], near, window)
                p = path.project_in_python(x[i], y[i], near, window)
                assert _same(c, p), (name, i, near, window, c, p)
                checked += 1
    assert checked == 400 * 5 * 2


def test_a_point_that_is_not_a_number_projects_as_in_python() -> None:
    for path in _paths().values():
        for x, y, near in ((math.nan, 0.0, None), (0.0, math.inf, 3.0), (math.nan, 1.0, 5.0)):
            assert _same(path.project(x, y, near), path.project_in_python(x, y, near))


@pytest.mark.parametrize("name", ["open", "closed", "crossing"])
def test_the_horizon_in_c_is_numpys_to_the_bit(name: str) -> None:
    """The spline reference of 200 horizons (cars on and off the path, slow, fast, some
    speeds negative or NaN, the car's heading whole turns away, stages beyond the end of an
    open path) with the C and in numpy throughout: the same numbers to the bit."""
    path = _paths()[name]
    plain = copy.copy(path)
    plain.__dict__["_compiled"] = None  # numpy and plain floats throughout
    rng = np.random.default_rng(5)
    for i in range(200):
        s0 = rng.uniform(0.0, path.length_m)
        point = path.point(s0)
        x, y = point.x_m + rng.normal(0.0, 1.0), point.y_m + rng.normal(0.0, 1.0)
        yaw = point.yaw_rad + rng.normal(0.0, 0.2) + 2.0 * np.pi * rng.integers(-2, 3)
        speeds = rng.uniform(-2.0, 30.0 if i % 2 else 300.0, 26)
        if i % 50 == 7:
            speeds[3] = math.nan
        got = horizon_reference("spline", path, x, y, yaw, speeds, 0.05)
        expected = horizon_reference("spline", plain, x, y, yaw, speeds, 0.05)
        for field in ("s_m", "x_m", "y_m", "yaw_rad", "curvature_1pm"):
            np.testing.assert_array_equal(getattr(got, field), getattr(expected, field),
                                          err_msg=f"{name} horizon {i}: {field}")


def test_one_angle_wraps_as_numpy_wraps_an_array() -> None:
    """wrap_angle of one float (plain floats) and of an array (numpy): the same numbers to
    the bit, multiples of pi and their neighbours, huge, tiny, infinite and NaN included."""
    rng = np.random.default_rng(2)
    multiples = np.arange(-50, 51) * np.pi
    angles = np.concatenate([
        rng.normal(0.0, 1.0, 20000), rng.normal(0.0, 1e3, 5000), multiples,
        np.nextafter(multiples, np.inf), np.nextafter(multiples, -np.inf),
        [0.0, -0.0, 1e300, -1e300, 5e-324, -5e-324, math.inf, -math.inf, math.nan]])
    with np.errstate(invalid="ignore"):
        arrays = wrap_angle(angles)
    floats = np.array([wrap_angle(a) for a in angles.tolist()])
    assert type(wrap_angle(0.5)) is float
    np.testing.assert_array_equal(floats, arrays)
    assert np.array_equal(np.signbit(floats), np.signbit(arrays))
