"""Speed planning along the horizon (tracker.mpc.grip_speed): cornering limits and braking
distances a reader can check by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tracker.mpc.grip_config import GripConfig
from tracker.mpc.grip_speed import (
    CurvatureTable,
    cannot_bind,
    capped_reference_speed,
    cornering_speed_cap,
)
from tracker.paths.double_lane_change import double_lane_change
from tracker.paths.reference_path import ReferencePath
from tracker.paths.shapes import circle, from_curvature

G = 9.81
GRIP = GripConfig()
MU = 0.6
LATERAL = GRIP.usage_max * MU * G
DECEL = GRIP.brake_usage * MU * G


def test_on_a_circle_the_cap_is_the_cornering_speed() -> None:
    """R = 50 m at friction 0.6: ``v = sqrt(0.85 mu g R)`` = 15.8 m/s everywhere (to the
    spline's wobble of its curvature between the points)."""
    shape = circle(50.0)
    path = ReferencePath(shape.x_m, shape.y_m, 20.0, closed=True)
    stages = np.linspace(10.0, 35.0, 25)
    capped = capped_reference_speed(path, stages, np.full(25, 20.0), 20.0, MU, GRIP)
    assert capped.reduced
    np.testing.assert_allclose(capped.speed_mps, math.sqrt(LATERAL * 50.0), rtol=1e-2)
    slow = capped_reference_speed(path, stages, np.full(25, 10.0), 10.0, MU, GRIP)
    assert not slow.reduced and np.all(slow.speed_mps == 10.0)


def test_before_a_bend_the_cap_is_the_speed_the_car_can_brake_from() -> None:
    """200 m straight, the curvature ramped to 1/50 m over 20 m, then R = 50 m: the cap at
    each stage is ``min_s sqrt(v_lim(s)^2 + 2 a_brake (s - s_k))``, computed here by brute
    force on a 1 cm grid from the curvature the path was built with (about 22.0, 18.6 and
    16.5 m/s at 50, 20 and 5 m before the end of the ramp)."""

    def kappa(s_m: np.ndarray) -> np.ndarray:
        return np.clip((s_m - 200.0) / 20.0, 0.0, 1.0) / 50.0

    s = np.arange(0.0, 400.0, 0.5)
    x, y = from_curvature(s, kappa(s))
    path = ReferencePath(x, y, 20.0)
    stages = 220.0 - np.array([50.0, 20.0, 5.0])
    cap = cornering_speed_cap(path, stages, 20.0, MU, GRIP)
    fine = np.arange(150.0, 350.0, 0.01)
    limit_sq = LATERAL / np.maximum(kappa(fine), 1e-9)
    expected = [math.sqrt(np.min((limit_sq + 2.0 * DECEL * (fine - s_k))[fine >= s_k]))
                for s_k in stages]
    np.testing.assert_allclose(cap, expected, rtol=5e-3)
    assert cap[2] < 17.0


def test_the_dry_lane_change_is_never_slowed() -> None:
    """The stretched lane change (0.5 g at 20 m/s) fits within 0.85 of friction 1.0 but
    not of 0.5, where the bend's speed is ``sqrt(0.85 * 0.5 g / kappa_max)``."""
    path = double_lane_change(20.0, 1.5)
    stages = np.arange(0.0, path.length_m - 30.0, 1.0)
    dry = cornering_speed_cap(path, stages, 20.0, 1.0, GRIP)
    assert np.min(dry) > 20.0
    wet = cornering_speed_cap(path, stages, 20.0, 0.5, GRIP)
    kappa_max = np.max(np.abs(path.sample(stages)["curvature_1pm"]))
    assert np.min(wet) == pytest.approx(math.sqrt(GRIP.usage_max * 0.5 * G / kappa_max),
                                        rel=1e-3)
    assert np.min(wet) < 19.0


def test_the_curvature_table_matches_the_spline_between_its_points() -> None:
    """The per-path table (1 m) against the spline itself at arbitrary arc lengths, on the
    lane change (peak curvature 0.0124 1/m; the spline's curvature wiggles between its
    waypoints by up to 0.0003 1/m, which linear interpolation smooths: the cap's speed
    moves by at most half the curvature's 2.4 %) and around a closed circle (wrapping)."""
    path = double_lane_change(20.0, 1.5)
    s = np.random.default_rng(0).uniform(0.0, path.length_m, 500)
    exact = np.abs(path.sample(s)["curvature_1pm"])
    np.testing.assert_allclose(CurvatureTable(path)(s), exact, atol=0.03 * np.max(exact))
    shape = circle(50.0)
    ring = ReferencePath(shape.x_m, shape.y_m, 20.0, closed=True)
    beyond = np.array([ring.length_m + 3.3, -2.5])
    np.testing.assert_allclose(CurvatureTable(ring)(beyond), 1.0 / 50.0, rtol=1e-2)


def _full_cap(path: ReferencePath, stages: np.ndarray, reference: np.ndarray,
              speed_now: float, friction: float) -> np.ndarray:
    """(V3) evaluated in full, without the shortcut."""
    return np.minimum(reference, cornering_speed_cap(path, stages, speed_now, friction, GRIP))


@pytest.mark.parametrize("closed", [False, True])
def test_the_shortcut_gives_the_full_caps_speeds_to_the_bit(closed: bool) -> None:
    """Where (V2) cannot bind the speeds are returned unevaluated: on 400 horizons along
    the lane change (open) and a 50 m circle with a straight (closed), at frictions 0.2-1.1
    and speeds 5-30 m/s, the shortcut is taken and not taken (both counted) and the speeds
    and the verdict are always those of (V2)-(V3) evaluated in full, bit for bit."""
    rng = np.random.default_rng(7)
    if closed:
        s = np.arange(0.0, 500.0, 0.5)
        x, y = from_curvature(s, np.where((s > 100.0) & (s < 100.0 + 100.0 * math.pi),
                                          1.0 / 50.0, 0.0))
        path = ReferencePath(x, y, 20.0, closed=True)
    else:
        path = double_lane_change(20.0, 1.5)
    table = CurvatureTable(path)
    taken = 0
    for _ in range(400):
        friction, speed = rng.uniform(0.2, 1.1), rng.uniform(5.0, 30.0)
        first = rng.uniform(-10.0, path.length_m + (20.0 if closed else 10.0))
        stages = first + np.cumsum(np.full(25, speed * 0.05))
        reference = speed + rng.uniform(-1.0, 1.0, 25)
        capped = capped_reference_speed(table, stages, reference, speed, friction, GRIP)
        full = _full_cap(path, stages, reference, speed, friction)
        taken += cannot_bind(table, stages, reference, speed, friction, GRIP)
        assert np.array_equal(capped.speed_mps, full)
        assert capped.reduced == bool(np.any(full < reference))
    assert taken >= 20 and 400 - taken >= 20  # both ways tried


def test_the_shortcut_is_taken_on_the_dry_lane_change() -> None:
    """The default lane change at 20 m/s on a dry road never binds the cap (module
    docstring), and every horizon along it skips (V2); at friction 0.5 the bends bind it
    and the horizons before them evaluate it."""
    path = double_lane_change(20.0, 1.5)
    table = CurvatureTable(path)
    starts = np.arange(0.0, path.length_m - 30.0, 2.0)
    horizons = [start + np.arange(1, 26) * 1.0 for start in starts]
    reference = np.full(25, 20.0)
    assert all(cannot_bind(table, s, reference, 20.0, 1.0, GRIP) for s in horizons)
    assert not all(cannot_bind(table, s, reference, 20.0, 0.5, GRIP) for s in horizons)
