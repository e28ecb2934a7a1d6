"""Comfort metrics, the speed profile in the speed error, gates and track limits, by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosim.core.config_fields import from_dict
from cosim.core.initial_state import InitialState
from cosim.core.records import VehicleState
from cosim.core.vehicle_params import PlantConfig
from cosim.simulation.course import Course, TrackBounds, build_course
from cosim.simulation.course_metrics import CourseMonitor
from cosim.simulation.metrics import MetricsAccumulator
from cosim.simulation.path_config import PathConfig
from tracker.paths.reference_path import ReferencePath
from tracker.paths.speed_profile import TimedSpeed


def _state(t: float, x: float = 0.0, y: float = 0.0, yaw: float = 0.0, vx: float = 10.0,
           ax: float = 0.0, ay: float = 0.0) -> VehicleState:
    return VehicleState(t, x, y, 0.5, 0.0, 0.0, yaw, vx, 0.0, 0.0, ax, ay, 0.0,
                        (0.0, 0.0, 0.0, 0.0))


def _straight(speed: float | TimedSpeed = 10.0) -> ReferencePath:
    x = np.linspace(0.0, 500.0, 11)
    return ReferencePath(x, np.zeros_like(x), speed)


def test_comfort_metrics_of_a_sinusoidal_lateral_acceleration() -> None:
    # a_y = A sin(w t): peak A, lateral jerk A w cos(w t) with RMS A w / sqrt(2); a_x = 0.
    metrics = MetricsAccumulator(_straight())
    amplitude, omega = 3.0, 2.0 * math.pi * 0.5
    for t in np.arange(0.0, 10.0 + 1e-9, 0.001):
        metrics.add_truth(_state(t, x=10.0 * t, ay=amplitude * math.sin(omega * t)))
    comfort = metrics.comfort()
    assert comfort["lat_accel_max_mps2"] == pytest.approx(amplitude, rel=1e-4)
    assert comfort["lat_jerk_rms_mps3"] == pytest.approx(amplitude * omega / math.sqrt(2),
                                                         rel=1e-3)
    assert comfort["jerk_rms_mps3"] == pytest.approx(comfort["lat_jerk_rms_mps3"], rel=1e-9)


def test_comfort_leaves_out_the_sample_before_the_first_step() -> None:
    metrics = MetricsAccumulator(_straight())
    metrics.add_truth(_state(0.0, ax=0.0))
    for k in range(1, 100):
        metrics.add_truth(_state(0.01 * k, x=0.1 * k, ax=3.0))
    assert metrics.comfort()["jerk_rms_mps3"] == 0.0


def test_speed_error_is_against_the_profile_at_that_time() -> None:
    profile = TimedSpeed(np.array([0.0, 10.0]), np.array([10.0, 0.0]))
    metrics = MetricsAccumulator(_straight(profile))
    metrics.add_truth(_state(5.0, x=50.0, vx=6.0))  # reference 5 m/s at 5 s
    assert metrics.last_speed_err_mps == pytest.approx(1.0)
    assert metrics.last_ref_speed_mps == pytest.approx(5.0)


def test_iso_gate_is_hit_by_a_car_drifting_out_of_the_first_lane() -> None:
    plant = from_dict(PlantConfig, {})
    course = build_course(from_dict(PathConfig, {"kind": "iso-lane-change"}), InitialState(),
                          plant, 14.0)
    clean, drifting = CourseMonitor(course, plant), CourseMonitor(course, plant)
    for x in np.arange(0.0, 70.0, 0.5):
        clean.add_truth(_state(0.0, x=x), 0.0, x)
        drifting.add_truth(_state(0.0, x=x, y=0.4), 0.4, x)  # lane 1 leaves 0.215 m a side
    assert clean.result()["gates_hit"] == 0
    assert drifting.result() == {"gates_hit": 1, "gate_1_passed": False,
                                 "gate_3_passed": True, "gate_5_passed": True,
                                 "gate_6_passed": True}


def test_track_limit_exceedances_count_excursions_not_samples() -> None:
    plant = from_dict(PlantConfig, {})
    reference = _straight()
    bounds = TrackBounds(np.array([0.0, 500.0]), np.array([2.0, 2.0]), np.array([2.0, 2.0]))
    monitor = CourseMonitor(Course(reference, bounds=bounds), plant)
    half_width = (plant.track_m + 0.2) / 2.0
    offsets = [0.0] * 5 + [2.5 - half_width] * 5 + [0.0] * 5 + [-(2.5 - half_width)] * 3
    for k, offset in enumerate(offsets):
        monitor.add_truth(_state(0.0, x=float(k), y=offset), offset, float(k))
    assert monitor.result() == {"track_limit_exceedances": 2}


def test_laps_on_a_circle_by_hand() -> None:
    # A 50 m circle driven at 10 m/s from its start line: a lap is 2 pi 50 / 10 = 31.4 s.
    radius, speed = 50.0, 10.0
    theta = np.linspace(0.0, 2.0 * np.pi, 200, endpoint=False)
    circle = ReferencePath(radius * np.sin(theta), radius * (1.0 - np.cos(theta)), speed,
                           closed=True)
    monitor = CourseMonitor(Course(circle), PlantConfig())
    lap_s = 2.0 * np.pi * radius / speed
    for t in np.arange(0.0, 2.5 * lap_s, 0.01):
        angle = speed * t / radius
        x, y = radius * np.sin(angle), radius * (1.0 - np.cos(angle)) + 0.3 * (t > 1.1 * lap_s)
        projection = circle.project(x, y)
        monitor.add_truth(_state(t, x, y, angle, ay=speed**2 / radius),
                          projection.lateral_error_m, projection.s_m)
    result = monitor.result()
    assert result["laps_completed"] == 2
    assert result["lap_time_s"] == pytest.approx(lap_s, abs=1e-3)
    assert result["lap_2_time_s"] == pytest.approx(lap_s, abs=1e-3)
    assert result["lap_1_cte_max_m"] < 1e-3 and result["lap_2_cte_max_m"] == pytest.approx(
        0.3, abs=1e-3)
    assert result["lap_1_lat_accel_max_mps2"] == pytest.approx(2.0)


def test_an_open_path_has_no_laps() -> None:
    monitor = CourseMonitor(Course(_straight()), PlantConfig())
    monitor.add_truth(_state(0.0), 0.0, 0.0)
    assert "laps_completed" not in monitor.result()
