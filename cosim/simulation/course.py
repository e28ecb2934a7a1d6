"""The course of a run: the reference path with its speed profile, and what lines it.

:func:`build_course` turns the ``path:`` section into a :class:`Course`: the
:class:`~tracker.paths.reference_path.ReferencePath` the tracker follows, plus what the run checks
and draws but the tracker never sees as such: the ISO 3888-1 cone gates
(:mod:`tracker.paths.iso3888`), the slalom's cones, and a circuit's track bounds (half-widths
to each side of the centre line, from the CSV).

A circuit is moved so that its first centre-line point is at the origin and the centre
line leaves it along +x, where the car starts by default. A ``path.file`` is looked up
relative to the working directory, then among the built-in
circuits in ``cosim/scenarios/tracks/`` (``path.file: ring.csv``).
"""

from __future__ import annotations

import importlib.resources
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from cosim.core.exceptions import ConfigError
from cosim.core.initial_state import InitialState
from cosim.core.vehicle_params import CarParams
from cosim.log.foxglove import BODY_WIDTH_OVER_TRACK_M
from cosim.simulation.path_config import PathConfig
from tracker.paths import iso3888, shapes
from tracker.paths.double_lane_change import double_lane_change
from tracker.paths.reference_path import ReferencePath
from tracker.paths.speed_profile import (
    ConstantSpeed,
    SpatialSpeed,
    SpeedProfile,
    friction_limited,
    stop_and_go,
)
from tracker.paths.track_csv import load_track


@dataclass(frozen=True)
class TrackBounds:
    """Half-widths of the track to each side of the reference path, per arc length."""

    s_m: np.ndarray
    width_left_m: np.ndarray
    width_right_m: np.ndarray

    def at(self, s_m: float, period_m: float | None) -> tuple[float, float]:
        """``(left, right)`` half-widths at arc length ``s_m``."""
        return (float(np.interp(s_m, self.s_m, self.width_left_m, period=period_m)),
                float(np.interp(s_m, self.s_m, self.width_right_m, period=period_m)))

    def edges(self, reference: ReferencePath, step_m: float = 1.0) -> tuple[np.ndarray, ...]:
        """World points of the left and right edges: ``x_left, y_left, x_right, y_right``."""
        s = np.arange(0.0, reference.length_m, step_m)
        samples = reference.sample(s)
        period = reference.length_m if reference.closed else None
        left = np.interp(s, self.s_m, self.width_left_m, period=period)
        right = np.interp(s, self.s_m, self.width_right_m, period=period)
        nx, ny = -np.sin(samples["yaw_rad"]), np.cos(samples["yaw_rad"])
        return (samples["x_m"] + left * nx, samples["y_m"] + left * ny,
                samples["x_m"] - right * nx, samples["y_m"] - right * ny)


@dataclass(frozen=True)
class Course:
    """Everything laid out on the ground for a run."""

    reference: ReferencePath
    gates: tuple[iso3888.Gate, ...] = ()
    cones_xy_m: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    bounds: TrackBounds | None = None


def body_width_m(vehicle: CarParams) -> float:
    """The car's body width: the wider track plus the body's overhang past the wheels."""
    return vehicle.widest_track_m + BODY_WIDTH_OVER_TRACK_M


def resolve_track_file(name: str) -> Path:
    """``name`` as given, else a built-in circuit of that name."""
    if not name:
        raise ConfigError("path.file = '': expected a centre-line CSV for path.kind track")
    path = Path(name)
    if path.exists():
        return path
    builtin = importlib.resources.files("cosim.scenarios") / "tracks" / name
    if builtin.is_file():
        return Path(str(builtin))
    raise ConfigError(f"path.file = {name!r}: no such file (nor a built-in circuit)")


def _profile(path: PathConfig, shape: shapes.Shape, duration_s: float) -> SpeedProfile:
    if path.speed_profile == "constant":
        return ConstantSpeed(path.speed_mps)
    if path.speed_profile == "stop-and-go":
        return stop_and_go(path.speed_mps, path.cruise_s, path.stop_s, path.accel_max_mps2,
                           path.decel_max_mps2, duration_s)
    geometry = ReferencePath(shape.x_m, shape.y_m, path.speed_mps, closed=shape.closed)
    s = np.arange(0.0, geometry.length_m, 1.0)
    speed = friction_limited(s, geometry.sample(s)["curvature_1pm"], path.speed_mps,
                             path.lat_accel_max_mps2, path.accel_max_mps2,
                             path.decel_max_mps2, shape.closed)
    return SpatialSpeed(s, speed, geometry.length_m if shape.closed else None)


def build_course(path: PathConfig, initial: InitialState, plant: CarParams,
                 duration_s: float) -> Course:
    """The course the ``path:`` section describes (``plant`` sizes the ISO gates)."""
    if path.kind == "double-lane-change":
        # Falcone's path keeps its own point list and stays bit for bit as it was.
        reference = double_lane_change(path.speed_mps, path.stretch, path.length_m)
        if path.speed_profile != "constant":
            shape = shapes.Shape(*_points(reference), False)
            reference = ReferencePath(shape.x_m, shape.y_m, _profile(path, shape, duration_s))
        return Course(reference)
    if path.kind == "straight":
        x_m = np.linspace(0.0, path.length_m, 4) + initial.x_m
        shape = shapes.Shape(x_m, np.full(4, initial.y_m), False)
        return Course(ReferencePath(shape.x_m, shape.y_m, _profile(path, shape, duration_s)))
    gates: tuple[iso3888.Gate, ...] = ()
    cones = np.zeros((0, 2))
    bounds = None
    if path.kind == "iso-lane-change":
        width = path.vehicle_width_m or body_width_m(plant)
        gates = iso3888.gates(width, path.approach_m)
        cones = np.vstack([g.cones() for g in gates])
        shape = iso3888.centre_line(gates, path.length_m)
    elif path.kind == "circle":
        shape = shapes.circle(path.radius_m)
    elif path.kind == "figure-eight":
        shape = shapes.figure_eight(path.radius_m)
    elif path.kind == "slalom":
        shape = shapes.slalom(path.spacing_m, path.cones, path.amplitude_m, path.approach_m,
                              path.length_m)
        cones = shapes.slalom_cones(path.spacing_m, path.cones, path.approach_m)
    elif path.kind == "s-curve":
        shape = shapes.s_curve(path.radius_m, path.arc_deg, path.approach_m, path.length_m)
    elif path.kind == "track":
        track = load_track(resolve_track_file(path.file))
        shape = shapes.Shape(*_to_start_frame(track.x_m, track.y_m), path.closed)
        geometry = ReferencePath(shape.x_m, shape.y_m, 1.0, closed=shape.closed)
        s_points = np.array([geometry.project(x, y).s_m
                             for x, y in zip(shape.x_m, shape.y_m, strict=True)])
        s_points[0] = 0.0
        order = np.argsort(s_points)
        default = np.full(track.x_m.size, path.default_width_m)
        left = track.width_left_m if track.width_left_m is not None else default
        right = track.width_right_m if track.width_right_m is not None else default
        bounds = TrackBounds(s_points[order], left[order], right[order])
    else:  # validated by choices
        raise AssertionError(f"unhandled path kind {path.kind!r}")
    reference = ReferencePath(shape.x_m, shape.y_m, _profile(path, shape, duration_s),
                              closed=shape.closed)
    return Course(reference, gates, cones, bounds)


def _points(reference: ReferencePath) -> tuple[np.ndarray, np.ndarray]:
    samples = reference.sample(np.arange(0.0, reference.length_m, 0.5))
    return samples["x_m"], samples["y_m"]


def _to_start_frame(x_m: np.ndarray, y_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points moved so the first is at the origin and the first segment points along +x."""
    dx, dy = x_m - x_m[0], y_m - y_m[0]
    heading = np.arctan2(dy[1], dx[1])
    c, s = np.cos(heading), np.sin(heading)
    return c * dx + s * dy, -s * dx + c * dy
