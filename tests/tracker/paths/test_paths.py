"""Paths and speed profiles: shapes, ISO 3888-1 gates, the circuit CSV loader, closed paths."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from cosim.core.exceptions import ConfigError
from tracker.paths import iso3888, shapes
from tracker.paths.reference_path import ReferencePath
from tracker.paths.speed_profile import SpatialSpeed, friction_limited, stop_and_go
from tracker.paths.track_csv import SelfIntersectionWarning, load_track


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "track.csv"
    path.write_text(text)
    return path


def test_racetrack_database_csv_is_read_with_its_widths(tmp_path: Path) -> None:
    path = _write(tmp_path, "# x_m,y_m,w_tr_right_m,w_tr_left_m\n"
                            "0,0,4,5\n10,0,4,5\n10,10,3,5\n0,10,4,6\n")
    track = load_track(path)
    np.testing.assert_array_equal(track.x_m, [0, 10, 10, 0])
    np.testing.assert_array_equal(track.width_right_m, [4, 4, 3, 4])
    np.testing.assert_array_equal(track.width_left_m, [5, 5, 5, 6])


def test_plain_xy_csv_is_read_with_or_without_a_header(tmp_path: Path) -> None:
    for text in ("x,y\n0,0\n5,0\n5,5\n", "0,0\n5,0\n5,5\n", "x_m,y_m\n0,0\n5,0\n5,5\n",
                 "# x_m,y_m\n0,0\n5,0\n5,5\n"):
        track = load_track(_write(tmp_path, text))
        np.testing.assert_array_equal(track.y_m, [0, 0, 5])
        assert track.width_left_m is None


@pytest.mark.parametrize(("text", "fragment"), [
    ("# x_m,y_m,w_tr_right_m\n0,0,1\n1,0,1\n1,1,1\n", "missing column(s) w_tr_left_m"),
    ("x,y\n0,0\n1,0\n", "2 distinct point(s), expected at least 3"),
    ("x,y\n3,4\n", "1 distinct point(s), expected at least 3"),
    ("x,y\n0,0\n1,0\n0,0\n1,0\n", "2 distinct point(s)"),
    ("x,y\n0,0\n1,nan\n2,2\n", "data row 2 is not finite"),
    ("x,y\n0,0\n1,0\n1,0\n2,2\n", "data rows 2 and 3 are the same point"),
    ("x,y\n0,0\n1\n2,2\n", "data row 2 has 1 column(s)"),
    ("x,y\n0,0\n1,abc\n2,2\n", "expected numbers"),
    ("x,y,width\n0,0,8\n10,0,8\n10,10,8\n", "column(s) width would not be read"),
    ("0,0,8\n10,0,8\n10,10,8\n", "3 columns and no header"),
    ("x;y\n0;0\n10;0\n10;10\n", "columns separated by semicolons"),
    ("0\t0\n10\t0\n10\t10\n", "columns separated by tabs"),
])
def test_bad_csv_is_one_clear_error(tmp_path: Path, text: str, fragment: str) -> None:
    with pytest.raises(ConfigError) as error:
        load_track(_write(tmp_path, text))
    assert fragment in str(error.value)
    assert "\n" not in str(error.value)


def test_a_centre_line_in_centimetres_is_said(tmp_path: Path) -> None:
    from tracker.paths.track_csv import TrackScaleWarning

    square_cm = "x,y\n0,0\n20000,0\n20000,20000\n0,20000\n"  # a 200 m square, in cm
    with pytest.warns(TrackScaleWarning, match="are the coordinates in metres"):
        load_track(_write(tmp_path, square_cm))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load_track(_write(tmp_path, "x,y\n0,0\n20,0\n20,20\n0,20\n"))


def test_self_intersecting_centre_line_is_a_warning(tmp_path: Path) -> None:
    bow_tie = "x,y\n0,0\n10,10\n10,0\n0,10\n"
    with pytest.warns(SelfIntersectionWarning):
        load_track(_write(tmp_path, bow_tie))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load_track(_write(tmp_path, "x,y\n0,0\n10,0\n10,10\n0,10\n"))


def test_closed_path_wraps_arc_length_and_projects_across_the_start() -> None:
    circle = shapes.circle(20.0)
    path = ReferencePath(circle.x_m, circle.y_m, 10.0, closed=True)
    assert path.length_m == pytest.approx(2 * math.pi * 20.0, rel=1e-4)
    a, b = path.point(1.0), path.point(1.0 + path.length_m)
    assert (a.x_m, a.y_m) == pytest.approx((b.x_m, b.y_m))
    assert path.point(5.0).curvature_1pm == pytest.approx(1 / 20.0, rel=1e-3)
    # Half a metre outside the circle, just before the start line: CTE -0.5 (right).
    projection = path.project(-0.3, -0.5)
    assert projection.lateral_error_m == pytest.approx(-0.5, abs=0.01)
    assert projection.s_m > path.length_m - 1.0


def test_friction_limited_profile_respects_corner_and_braking_limits() -> None:
    # 100 m straight then a 20 m radius corner: corner speed sqrt(5 * 20) = 10 m/s, and the
    # car must brake at 4 m/s^2 from 30 m/s to reach it: 100 m before it.
    s = np.arange(0.0, 300.0, 1.0)
    kappa = np.where((s >= 200.0) & (s < 240.0), 1 / 20.0, 0.0)
    v = friction_limited(s, kappa, 30.0, 5.0, 2.0, 4.0, closed=False)
    assert v[210] == pytest.approx(10.0)
    assert np.all(v <= 30.0 + 1e-9)
    braking = (v[:-1] ** 2 - v[1:] ** 2) / 2.0  # per metre
    assert np.all(braking <= 4.0 + 1e-9)
    accel = (v[1:] ** 2 - v[:-1] ** 2) / 2.0
    assert np.all(accel <= 2.0 + 1e-9)
    # At the corner's first point (200 m) cornering takes all the grip (the friction
    # ellipse leaves no braking), so braking ends at 199 m: v^2 = 10^2 + 2 * 4 * d before it.
    assert v[199] == pytest.approx(10.0)
    assert v[150] == pytest.approx(math.sqrt(100.0 + 8.0 * 49.0), rel=1e-9)
    assert v[98] == pytest.approx(30.0)


def test_spatial_profile_wraps_on_a_closed_path() -> None:
    profile = SpatialSpeed(np.array([0.0, 50.0]), np.array([10.0, 20.0]), period_m=100.0)
    assert profile.speed_mps(np.array([125.0]), np.array([0.0]))[0] == pytest.approx(15.0)
    assert profile.speed_mps(np.array([75.0]), np.array([0.0]))[0] == pytest.approx(15.0)


def test_stop_and_go_stands_still_then_goes_again() -> None:
    profile = stop_and_go(12.0, cruise_s=4.0, stop_s=2.0, accel_mps2=2.0, decel_mps2=3.0,
                          duration_s=30.0)
    v = profile.speed_mps(np.zeros(4), np.array([2.0, 6.0, 9.0, 16.0]))
    # Cruise to 4 s, brake 4 s to rest at 8 s, stand to 10 s, accelerate 6 s to 12 m/s.
    np.testing.assert_allclose(v, [12.0, 6.0, 0.0, 12.0])


def test_iso_gates_follow_the_standards_table() -> None:
    width = 1.8
    gates = iso3888.gates(width, start_x_m=50.0)
    assert [g.section for g in gates] == [1, 3, 5, 6]
    assert [g.x_start_m for g in gates] == [50.0, 95.0, 145.0, 160.0]
    assert [g.x_end_m - g.x_start_m for g in gates] == [15.0, 25.0, 15.0, 15.0]
    widths = [g.y_left_m - g.y_right_m for g in gates]
    assert widths == pytest.approx([1.1 * width + 0.25, 1.2 * width + 0.25,
                                    1.3 * width + 0.25, 1.3 * width + 0.25])
    assert gates[1].y_right_m == pytest.approx(3.5)
    assert gates[2].y_right_m == pytest.approx(gates[0].y_right_m)


def test_iso_gate_hit_by_a_corner_outside_a_cone_line() -> None:
    gate = iso3888.gates(1.8, 50.0)[0]
    inside = iso3888.corners(57.0, 0.0, 0.0, 2.0, 2.0, 0.9)
    assert not iso3888.gate_hit(gate, inside)
    assert iso3888.gate_hit(gate, iso3888.corners(57.0, 0.35, 0.0, 2.0, 2.0, 0.9))
    # Far before the gate the same offset is no hit.
    assert not iso3888.gate_hit(gate, iso3888.corners(20.0, 0.35, 0.0, 2.0, 2.0, 0.9))


def test_iso_centre_line_runs_through_every_lane_centre() -> None:
    gates = iso3888.gates(1.8, 50.0)
    line = iso3888.centre_line(gates, 250.0)
    for gate in gates:
        inside = (line.x_m >= gate.x_start_m) & (line.x_m <= gate.x_end_m)
        np.testing.assert_allclose(line.y_m[inside], gate.centre_m, atol=1e-9)


@pytest.mark.parametrize("shape", [
    shapes.circle(40.0), shapes.figure_eight(30.0), shapes.s_curve(50.0, 90.0, 50.0, 400.0),
    shapes.slalom(20.0, 8, 1.5, 50.0, 300.0),
])
def test_shapes_start_at_the_origin_along_x_with_continuous_heading(
        shape: shapes.Shape) -> None:
    path = ReferencePath(shape.x_m, shape.y_m, 10.0, closed=shape.closed)
    start = path.point(0.0)
    assert (start.x_m, start.y_m) == pytest.approx((0.0, 0.0), abs=1e-6)
    assert abs(start.yaw_rad) < 0.02
    s = np.arange(0.0, path.length_m, 0.5)
    yaw = np.unwrap(path.sample(s)["yaw_rad"])
    assert np.max(np.abs(np.diff(yaw))) < 0.05  # no kink: < 0.05 rad per half metre


def test_figure_eight_crosses_itself_at_right_angles_and_closes() -> None:
    shape = shapes.figure_eight(30.0)
    path = ReferencePath(shape.x_m, shape.y_m, 10.0, closed=True)
    s = np.arange(0.0, path.length_m, 0.25)
    samples = path.sample(s)
    near = np.hypot(samples["x_m"], samples["y_m"]) < 0.3
    headings = np.degrees(samples["yaw_rad"][near])
    assert np.any(np.abs(headings) < 3.0) and np.any(np.abs(np.abs(headings) - 90.0) < 3.0)
    assert np.max(np.abs(samples["curvature_1pm"])) == pytest.approx(1 / 30.0, rel=0.05)


def _circle_rows(n: int = 40, radius: float = 30.0) -> list[tuple[float, float]]:
    return [(radius * math.cos(2 * math.pi * i / n), radius * math.sin(2 * math.pi * i / n))
            for i in range(n)]


@pytest.mark.parametrize("newline", ["\n", "\r\n"])
@pytest.mark.parametrize("racetrack", [False, True])
def test_a_byte_order_mark_and_crlf_lose_no_point(tmp_path: Path, newline: str,
                                                  racetrack: bool) -> None:
    rows = _circle_rows()
    lines = (["# x_m,y_m,w_tr_right_m,w_tr_left_m"] + [f"{x},{y},4,5" for x, y in rows]
             if racetrack else [f"{x},{y}" for x, y in rows])
    path = tmp_path / "bom.csv"
    path.write_bytes(b"\xef\xbb\xbf" + newline.join(lines).encode() + newline.encode())
    track = load_track(path)
    np.testing.assert_allclose(track.x_m, [x for x, _ in rows])
    assert (track.width_left_m is not None) == racetrack


def test_a_device_is_refused_without_reading_it() -> None:
    with pytest.raises(ConfigError, match="not a regular file"):
        load_track("/dev/zero")


@pytest.mark.parametrize(("rows", "closed", "fragment"), [
    ([(1e12 * x, 1e12 * y) for x, y in _circle_rows()], True, "coordinate beyond 1e+07 m"),
    ([(1e4 * x, 1e4 * y) for x, y in _circle_rows()], True, "m long: expected at most 100,000"),
    ([(float(x), 0.0) for x in range(0, 60, 2)] + [(float(x), 60.0) for x in range(60, 0, -2)],
     True, "its last point is 60.0 m from its first"),
    ([(float(x), 0.0) for x in range(0, 60, 2)] + [(float(x), 0.01) for x in range(58, -60, -2)],
     False, "the path turns back by 180 deg between data rows"),
])
def test_a_course_out_of_bounds_open_or_turning_back_is_refused(
        tmp_path: Path, rows: list[tuple[float, float]], closed: bool, fragment: str) -> None:
    path = _write(tmp_path, "x,y\n" + "".join(f"{x},{y}\n" for x, y in rows))
    with pytest.raises(ConfigError) as error:
        load_track(path, closed)
    assert fragment in str(error.value)


def test_an_open_path_is_accepted_when_said_open(tmp_path: Path) -> None:
    rows = [(float(x), 0.0) for x in range(0, 60, 2)]
    rows += [(60.0 + x, float(x)) for x in range(2, 40, 2)]
    text = "x,y\n" + "".join(f"{x},{y}\n" for x, y in rows)
    track = load_track(_write(tmp_path, text), False)
    assert len(track.x_m) == len(rows)


def _crossing_by_brute_force(x: np.ndarray, y: np.ndarray, closed: bool) -> int | None:
    """The plain O(n^2) reference: every pair of non-adjacent segments."""
    p = np.column_stack((x, y))
    n = len(p)
    segments = n if closed else n - 1

    def cross(o: np.ndarray, u: np.ndarray, v: np.ndarray) -> float:
        return float((u[0] - o[0]) * (v[1] - o[1]) - (u[1] - o[1]) * (v[0] - o[0]))

    for i in range(segments):
        for j in range(i + 2, segments):
            if closed and i == 0 and j == n - 1:
                continue
            a, b, c, d = p[i], p[(i + 1) % n], p[j], p[(j + 1) % n]
            if cross(c, d, a) * cross(c, d, b) < 0 and cross(a, b, c) * cross(a, b, d) < 0:
                return i
    return None


@pytest.mark.parametrize("seed", range(8))
@pytest.mark.parametrize("closed", [True, False])
def test_the_crossing_search_matches_the_brute_force(seed: int, closed: bool) -> None:
    from tracker.paths.track_csv import first_self_intersection

    rng = np.random.default_rng(seed)
    # A random walk with a turning heading and a few long strides (the k-d tree's
    # long-segment branch): it crosses itself at a random place, or not at all.
    heading = np.cumsum(rng.normal(0.0, 0.6, 50))
    stride = np.where(rng.uniform(size=50) < 0.05, 30.0, rng.uniform(1.0, 3.0, 50))
    x, y = np.cumsum(stride * np.cos(heading)), np.cumsum(stride * np.sin(heading))
    assert first_self_intersection(x, y, closed) == _crossing_by_brute_force(x, y, closed)


@pytest.mark.parametrize("closed", [True, False])
def test_one_speed_is_the_arrays_speed_to_the_bit(closed: bool) -> None:
    """``speed_ref_at`` (plain floats, for the metrics' every log instant) gives what
    ``speed_ref`` gives at the same arc length and time: wrapped on a closed path, clamped on
    an open one, for every kind of profile."""
    circle = shapes.circle(20.0)
    length = 2 * math.pi * 20.0
    profiles = [
        12.5,
        SpatialSpeed(np.array([0.0, 40.0, 90.0]), np.array([10.0, 20.0, 14.0]),
                     period_m=length if closed else None),
        # Breakpoints past the path's end: only the path's own wrap or clamp keeps to it.
        SpatialSpeed(np.array([-length, 0.0, 60.0, 2.0 * length]),
                     np.array([3.0, 10.0, 20.0, 30.0])),
        stop_and_go(12.0, cruise_s=4.0, stop_s=2.0, accel_mps2=2.0, decel_mps2=3.0,
                    duration_s=30.0),
    ]
    arcs = [0.0, -0.0, 3.7, -1e-12, -3.7, length - 1e-9, length, length + 0.3, 3 * length + 7.1,
            1e6, -1e6]
    for profile in profiles:
        path = ReferencePath(circle.x_m, circle.y_m, profile, closed=closed)
        for s_m in arcs:
            for t_s in (0.0, 5.5, 9.25, 40.0):
                expected = float(path.speed_ref(s_m, t_s))
                got = path.speed_ref_at(s_m, t_s)
                assert type(got) is float
                assert got == expected, (profile, s_m, t_s)
