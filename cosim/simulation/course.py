"""The course of a run: the reference path with its speed profile, and what lines it.

:func:`build_course` turns the ``path:`` section into a :class:`Course`: the
:class:`~tracker.paths.reference_path.ReferencePath` the tracker follows, plus what the run checks
and draws but the tracker never sees as such: the ISO 3888-1 cone gates
(:mod:`tracker.paths.iso3888`), the slalom's cones, and a circuit's track bounds (half-widths
to each side of the centre line, from the CSV).

A circuit (``path.kind: track`` from a CSV, or ``generated``: a procedural circuit of
:mod:`tracker.paths.generated_circuit`) is smoothed where its points are noisy
(``path.smoothing``, :mod:`tracker.paths.centre_line`), then moved so that its first
centre-line point is at the origin and the centre line leaves it along +x, where the car
starts by default. A ``path.file`` is looked up relative to the working directory, then
among the built-in circuits in ``cosim/scenarios/tracks/`` (``path.file: ring.csv``).

A friction-limited speed profile (:func:`tracker.paths.speed_profile.friction_limited`) is
kept within what the car and the tracker can do (:func:`profile_limits`): the lateral limit
and the braking within ``path.grip_share`` of the believed friction circle
(``tracker.model.tyre_friction`` g), the acceleration and the braking within
``path.tracking_share`` of the tracker's bounds (the rest is the speed loop's authority to
catch up), the acceleration within what the believed drive power gives at the top speed.
"""

from __future__ import annotations

import importlib.resources
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from cosim.core.exceptions import ConfigError
from cosim.core.initial_state import InitialState
from cosim.core.vehicle_params import CarParams, VehicleParams
from cosim.log.foxglove import BODY_WIDTH_OVER_TRACK_M
from cosim.simulation.path_config import PathConfig
from tracker.config import TrackerConfig
from tracker.paths import iso3888, shapes
from tracker.paths.centre_line import smooth_centre_line
from tracker.paths.double_lane_change import double_lane_change
from tracker.paths.reference_path import ReferencePath
from tracker.paths.speed_profile import (
    ConstantSpeed,
    SpatialSpeed,
    SpeedProfile,
    friction_limited,
    stop_and_go,
)
from tracker.paths.track_csv import TrackData, load_track

GRAVITY_MPS2 = 9.81
AIR_DENSITY_KGPM3 = 1.2


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
class ProfileLimits:
    """What a friction-limited speed profile may ask of the car [m/s^2]."""

    lat_accel_max_mps2: float
    accel_max_mps2: float
    decel_max_mps2: float


@dataclass(frozen=True)
class Course:
    """Everything laid out on the ground for a run."""

    reference: ReferencePath
    gates: tuple[iso3888.Gate, ...] = ()
    cones_xy_m: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    bounds: TrackBounds | None = None
    limits: ProfileLimits | None = None
    """The limits of a friction-limited speed profile (None for other profiles)."""


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


def profile_limits(path: PathConfig, tracker: TrackerConfig | None) -> ProfileLimits:
    """The limits of a friction-limited profile (module docstring): ``path``'s, within the
    car's believed grip and power and the tracker's bounds (``tracker`` None: ``path``'s)."""
    if tracker is None:
        return ProfileLimits(path.lat_accel_max_mps2, path.accel_max_mps2,
                             path.decel_max_mps2)
    belief: VehicleParams = tracker.model
    grip = path.grip_share * belief.tyre_friction * GRAVITY_MPS2
    top = max(path.speed_mps, 1.0)
    resistance_n = (0.5 * AIR_DENSITY_KGPM3 * belief.drag_area_m2 * top**2
                    + belief.rolling_resistance * belief.mass_kg * GRAVITY_MPS2)
    power_accel = (belief.max_drive_power_w / top - resistance_n) / belief.mass_kg
    return ProfileLimits(
        lat_accel_max_mps2=min(path.lat_accel_max_mps2, grip),
        accel_max_mps2=max(0.1, min(path.accel_max_mps2,
                                    path.tracking_share * tracker.accel_max_mps2,
                                    power_accel)),
        decel_max_mps2=min(path.decel_max_mps2, grip,
                           path.tracking_share * -tracker.accel_min_mps2),
    )


def _profile(path: PathConfig, shape: shapes.Shape, duration_s: float,
             limits: ProfileLimits) -> SpeedProfile:
    if path.speed_profile == "constant":
        return ConstantSpeed(path.speed_mps)
    if path.speed_profile == "stop-and-go":
        return stop_and_go(path.speed_mps, path.cruise_s, path.stop_s, path.accel_max_mps2,
                           path.decel_max_mps2, duration_s)
    geometry = ReferencePath(shape.x_m, shape.y_m, path.speed_mps, closed=shape.closed)
    s = np.arange(0.0, geometry.length_m, 1.0)
    speed = friction_limited(s, geometry.sample(s)["curvature_1pm"], path.speed_mps,
                             limits.lat_accel_max_mps2, limits.accel_max_mps2,
                             limits.decel_max_mps2, shape.closed)
    return SpatialSpeed(s, speed, geometry.length_m if shape.closed else None)


def build_course(path: PathConfig, initial: InitialState, plant: CarParams,
                 duration_s: float, tracker: TrackerConfig | None = None) -> Course:
    """The course the ``path:`` section describes (``plant`` sizes the ISO gates; the
    ``tracker``'s bounds and belief bound a friction-limited profile, :func:`profile_limits`)."""
    limits = profile_limits(path, tracker)
    if path.kind == "double-lane-change":
        # Falcone's path keeps its own point list and stays bit for bit as it was.
        reference = double_lane_change(path.speed_mps, path.stretch, path.length_m)
        if path.speed_profile != "constant":
            shape = shapes.Shape(*_points(reference), False)
            reference = ReferencePath(shape.x_m, shape.y_m,
                                      _profile(path, shape, duration_s, limits))
        return Course(reference, limits=_limits_if_used(path, limits))
    if path.kind == "straight":
        x_m = np.linspace(0.0, path.length_m, 4) + initial.x_m
        shape = shapes.Shape(x_m, np.full(4, initial.y_m), False)
        return Course(ReferencePath(shape.x_m, shape.y_m,
                                    _profile(path, shape, duration_s, limits)),
                      limits=_limits_if_used(path, limits))
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
        shape, bounds = _circuit(load_track(resolve_track_file(path.file), path.closed), path)
    elif path.kind == "generated":
        from tracker.paths.generated_circuit import generated_circuit  # its runs alone

        shape, bounds = _circuit(generated_circuit(path.seed), path)
    else:  # validated by choices
        raise AssertionError(f"unhandled path kind {path.kind!r}")
    reference = ReferencePath(shape.x_m, shape.y_m, _profile(path, shape, duration_s, limits),
                              closed=shape.closed)
    return Course(reference, gates, cones, bounds, _limits_if_used(path, limits))


def _limits_if_used(path: PathConfig, limits: ProfileLimits) -> ProfileLimits | None:
    return limits if path.speed_profile == "friction-limited" else None


def _circuit(track: TrackData, path: PathConfig) -> tuple[shapes.Shape, TrackBounds]:
    """A circuit's centre line (smoothed when noisy, in the start frame) and its bounds."""
    closed = path.closed if path.kind == "track" else True
    x_m, y_m = track.x_m, track.y_m
    if path.smoothing:
        line = smooth_centre_line(x_m, y_m, closed)
        x_m, y_m = line.x_m, line.y_m
    frame = _start_frame(x_m, y_m)
    shape = shapes.Shape(*frame.apply(x_m, y_m), closed)
    geometry = ReferencePath(shape.x_m, shape.y_m, 1.0, closed=shape.closed)
    raw_x, raw_y = frame.apply(track.x_m, track.y_m)
    # Each point's arc length: its chord length along the points, scaled to the path's,
    # refined by a projection searched near it (a search of the whole path per point
    # would cost the point count squared).
    chords = np.concatenate(([0.0], np.cumsum(np.hypot(np.diff(raw_x), np.diff(raw_y)))))
    guess = chords * geometry.length_m / max(chords[-1] + np.hypot(
        raw_x[-1] - raw_x[0], raw_y[-1] - raw_y[0]) * closed, 1e-9)
    s_points = np.array([geometry.project(x, y, near_s_m=g).s_m
                         for x, y, g in zip(raw_x, raw_y, guess, strict=True)])
    s_points[0] = 0.0
    order = np.argsort(s_points)
    default = np.full(track.x_m.size, path.default_width_m)
    left = track.width_left_m if track.width_left_m is not None else default
    right = track.width_right_m if track.width_right_m is not None else default
    return shape, TrackBounds(s_points[order], left[order], right[order])


def _points(reference: ReferencePath) -> tuple[np.ndarray, np.ndarray]:
    samples = reference.sample(np.arange(0.0, reference.length_m, 0.5))
    return samples["x_m"], samples["y_m"]


@dataclass(frozen=True)
class _StartFrame:
    """The rigid motion that puts a centre line's first point at the origin, heading +x."""

    x0_m: float
    y0_m: float
    heading_rad: float

    def apply(self, x_m: np.ndarray, y_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        dx, dy = x_m - self.x0_m, y_m - self.y0_m
        c, s = np.cos(self.heading_rad), np.sin(self.heading_rad)
        return c * dx + s * dy, -s * dx + c * dy


def _start_frame(x_m: np.ndarray, y_m: np.ndarray) -> _StartFrame:
    """The frame of the first point, along the first segment (of the smoothed line, when
    smoothed: a noisy first segment would tilt the start)."""
    return _StartFrame(float(x_m[0]), float(y_m[0]),
                       float(np.arctan2(y_m[1] - y_m[0], x_m[1] - x_m[0])))
