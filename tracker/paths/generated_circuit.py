"""Procedural closed circuits: held-out tracks that no one tuned for, one per seed.

``path.kind: generated`` with ``path.seed: N`` drives the N-th circuit; :func:`circuit_csv`
writes it in the racetrack-database layout a user would bring (:mod:`tracker.paths.track_csv`),
so a generated circuit and a user's file take the same road through the run.

A circuit is laid out as a turtle walks (the way circuits are drawn from straights and
constant-radius corners, e.g. the track-design chapters of Milliken and Milliken, "Race Car
Vehicle Dynamics", SAE 1995):

1. a target lap length, log-uniform in ``[LENGTH_MIN_M, LENGTH_MAX_M]``, and a number of
   features growing with it;
2. features in driving order, each followed by a straight: corners (radius log-uniform in
   ``[CORNER_RADIUS_MIN_M, CORNER_RADIUS_MAX_M]``, 20-120 degrees, a quarter of them
   right-handers), hairpins (radius down to ``HAIRPIN_RADIUS_MIN_M``, 150-190 degrees) and
   chicanes (two opposite short arcs, no net turn); the left-hand turns are scaled so that
   the turns add up to one counter-clockwise lap;
3. the straights' lengths close the loop: the end point is linear in them, so the lengths
   nearest to drawn ones (one long straight among them) that bring the walk back to its
   start solve a bounded linear least-squares problem (:func:`scipy.optimize.lsq_linear`);
4. the walk is sampled every 1-5 m (drawn per circuit, with jitter), the points get
   centimetre-level noise, as surveyed centre lines do, and the track a width of 6-15 m
   (drawn, varying smoothly along the lap);
5. a layout whose track would touch itself (two parts closer than their half-widths plus
   ``CLEARANCE_M``) or that cannot be closed is drawn again from the same generator.

The first point lies on the longest straight, ``START_BEFORE_END_M`` before its end (at
its start when it is shorter): a start-finish straight, from which the car brakes from top
speed into the next corner within seconds.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass

import numpy as np

from cosim.core.exceptions import ConfigError
from tracker.paths.track_csv import TrackData

LENGTH_MIN_M = 300.0
LENGTH_MAX_M = 3000.0
"""Range of the lap length drawn for a circuit (the closed layout lands near it) [m]."""
HAIRPIN_RADIUS_MIN_M = 12.0
HAIRPIN_RADIUS_MAX_M = 20.0
CORNER_RADIUS_MIN_M = 20.0
CORNER_RADIUS_MAX_M = 200.0
CHICANE_RADIUS_MIN_M = 15.0
CHICANE_RADIUS_MAX_M = 50.0
WIDTH_MIN_M = 6.0
WIDTH_MAX_M = 15.0
"""Range of the track's full width (both half-widths together) [m]."""
STRAIGHT_MIN_M = 15.0
"""The shortest straight between two features [m]."""
SPACING_MIN_M = 1.0
SPACING_MAX_M = 5.0
"""Range of the centre line's point spacing [m]."""
NOISE_MAX_M = 0.05
"""The points' noise per coordinate is drawn up to this [m]."""
CLEARANCE_M = 5.0
"""Least gap between the edges of two parts of the track that are not neighbours [m]."""
START_BEFORE_END_M = 150.0
"""The circuit starts this far before the end of its longest straight [m]."""
MAX_ATTEMPTS = 200
"""Layouts drawn before giving up (a seed that fails this often is a bug)."""


@dataclass(frozen=True)
class _Arc:
    radius_m: float
    angle_rad: float
    """Signed: positive turns left."""


@dataclass(frozen=True)
class _Feature:
    arcs: tuple[_Arc, ...]
    inner_straight_m: float = 0.0
    """A chicane's straight between its two arcs [m]."""


def _arc_displacement(heading_rad: float, arc: _Arc) -> np.ndarray:
    """Where an arc from the origin at ``heading_rad`` ends (signed curvature form)."""
    kappa = np.sign(arc.angle_rad) / arc.radius_m
    end = heading_rad + arc.angle_rad
    return np.array([np.sin(end) - np.sin(heading_rad), np.cos(heading_rad) - np.cos(end)]) \
        / kappa


def _draw_features(rng: np.random.Generator, length_m: float) -> list[_Feature] | None:
    count = int(np.clip(round(length_m / 220.0) + rng.integers(0, 3), 4, 14))
    features: list[_Feature] = []
    hairpins = int(rng.random() < 0.7) + int(length_m > 1500.0 and rng.random() < 0.5)
    for index in range(count):
        if index < hairpins:
            radius = rng.uniform(HAIRPIN_RADIUS_MIN_M, HAIRPIN_RADIUS_MAX_M)
            features.append(_Feature((_Arc(radius, np.radians(rng.uniform(150, 190))),)))
        elif rng.random() < 0.2:
            radius = rng.uniform(CHICANE_RADIUS_MIN_M, CHICANE_RADIUS_MAX_M)
            angle = np.radians(rng.uniform(20, 50)) * rng.choice((-1.0, 1.0))
            features.append(_Feature((_Arc(radius, angle), _Arc(radius, -angle)),
                                     rng.uniform(0.0, 12.0)))
        else:
            radius = float(np.exp(rng.uniform(np.log(CORNER_RADIUS_MIN_M),
                                              np.log(CORNER_RADIUS_MAX_M))))
            sign = -1.0 if rng.random() < 0.25 else 1.0
            features.append(_Feature((_Arc(radius, sign * np.radians(rng.uniform(20, 120))),)))
    rng.shuffle(features)  # type: ignore[arg-type]
    # Scale the left turns of single-arc features so the lap turns once, anticlockwise.
    singles = [f for f in features if len(f.arcs) == 1]
    left = sum(f.arcs[0].angle_rad for f in singles if f.arcs[0].angle_rad > 0)
    right = sum(-f.arcs[0].angle_rad for f in singles if f.arcs[0].angle_rad < 0)
    if left <= 0.0:
        return None
    scale = (2.0 * np.pi + right) / left
    scaled = []
    for feature in features:
        arc = feature.arcs[0]
        if len(feature.arcs) == 1 and arc.angle_rad > 0:
            angle = arc.angle_rad * scale
            if angle > np.radians(195):
                return None
            feature = _Feature((_Arc(arc.radius_m, angle),))
        scaled.append(feature)
    return scaled


def _close(rng: np.random.Generator, features: list[_Feature],
           length_m: float) -> np.ndarray | None:
    """Straight lengths after each feature that close the loop, or None."""
    heading, position = 0.0, np.zeros(2)
    directions = []
    arc_length = 0.0
    for feature in features:
        for i, arc in enumerate(feature.arcs):
            if i:  # a chicane's short straight between its arcs
                position += feature.inner_straight_m * np.array([np.cos(heading),
                                                                 np.sin(heading)])
                arc_length += feature.inner_straight_m
            position += _arc_displacement(heading, arc)
            heading += arc.angle_rad
            arc_length += arc.radius_m * abs(arc.angle_rad)
        directions.append([np.cos(heading), np.sin(heading)])
    count = len(features)
    budget = max(length_m - arc_length, STRAIGHT_MIN_M * count)
    share = rng.dirichlet(np.ones(count))
    share[rng.integers(count)] += 1.0  # one long straight
    wanted = np.maximum(budget * share / share.sum(), STRAIGHT_MIN_M)
    directions_m = np.asarray(directions).T  # 2 x count
    weight = 1e3
    a = np.vstack((weight * directions_m, np.eye(count)))
    b = np.concatenate((-weight * position, wanted))
    from scipy.optimize import lsq_linear  # here: heavy, and for generated circuits only

    solution = lsq_linear(a, b, bounds=(STRAIGHT_MIN_M, np.inf))
    lengths = solution.x
    if np.linalg.norm(directions_m @ lengths + position) > 0.05:
        return None
    return lengths


def _trace(features: list[_Feature], straights_m: np.ndarray,
           step_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Points every ``step_m`` along the layout, and the index range of each straight."""
    points, heading, position = [], 0.0, np.zeros(2)

    def run_straight(length_m: float) -> None:
        nonlocal position
        direction = np.array([np.cos(heading), np.sin(heading)])
        for d in np.arange(0.0, length_m, step_m):
            points.append(position + d * direction)
        position = position + length_m * direction

    spans = []
    for feature, straight in zip(features, straights_m, strict=True):
        for i, arc in enumerate(feature.arcs):
            if i:
                run_straight(feature.inner_straight_m)
            centre_angle = heading + np.sign(arc.angle_rad) * np.pi / 2
            centre = position + arc.radius_m * np.array([np.cos(centre_angle),
                                                         np.sin(centre_angle)])
            for phi in np.arange(0.0, abs(arc.angle_rad), step_m / arc.radius_m):
                angle = heading + np.sign(arc.angle_rad) * phi
                points.append(centre - arc.radius_m * np.array(
                    [np.cos(angle + np.sign(arc.angle_rad) * np.pi / 2),
                     np.sin(angle + np.sign(arc.angle_rad) * np.pi / 2)]))
            position = position + _arc_displacement(heading, arc)
            heading += arc.angle_rad
        start = len(points)
        run_straight(float(straight))
        spans.append((start, len(points)))
    xy = np.asarray(points)
    return xy, np.asarray(spans)


def _clear(xy: np.ndarray, width_m: np.ndarray, step_m: float) -> bool:
    """No two parts of the track (further apart along it than they could be across)
    closer than their half-widths plus :data:`CLEARANCE_M`."""
    n = len(xy)
    index = np.arange(n)
    apart = np.abs(index[:, None] - index[None, :])
    apart = np.minimum(apart, n - apart) * step_m  # along the lap, both ways round
    gap = np.hypot(xy[:, None, 0] - xy[None, :, 0], xy[:, None, 1] - xy[None, :, 1])
    need = 0.5 * (width_m[:, None] + width_m[None, :]) + CLEARANCE_M
    # Neighbours along the lap are close by construction: only pairs further apart along
    # the track than pi times the space they need (half a turn around it) count.
    far = apart > np.pi * need
    return not np.any(far & (gap < need))


def generated_circuit(seed: int) -> TrackData:
    """The circuit of generator seed ``seed`` (module docstring), deterministic."""
    rng = np.random.default_rng([seed, zlib.crc32(b"generated_circuit")])
    for _ in range(MAX_ATTEMPTS):
        length_m = float(np.exp(rng.uniform(np.log(LENGTH_MIN_M), np.log(LENGTH_MAX_M))))
        features = _draw_features(rng, length_m)
        if features is None:
            continue
        straights = _close(rng, features, length_m)
        if straights is None:
            continue
        check_step = 2.0
        xy, _ = _trace(features, straights, check_step)
        lap = len(xy) * check_step
        if not LENGTH_MIN_M <= lap <= LENGTH_MAX_M:
            continue
        width = _Width(rng.uniform(WIDTH_MIN_M, WIDTH_MAX_M), rng.uniform(0.0, 2.0 * np.pi),
                       int(rng.integers(1, 4)), lap)
        if not _clear(xy, width(np.arange(len(xy)) * check_step), check_step):
            continue
        return _sampled(rng, features, straights, width)
    raise ConfigError(f"path.seed = {seed}: no circuit found in {MAX_ATTEMPTS} layouts")


@dataclass(frozen=True)
class _Width:
    """The track's full width along the lap: ``base`` varying by 15 % in ``waves`` waves."""

    base_m: float
    phase_rad: float
    waves: int
    lap_m: float

    def __call__(self, s_m: np.ndarray) -> np.ndarray:
        wave = np.sin(2.0 * np.pi * self.waves * s_m / self.lap_m + self.phase_rad)
        return np.clip(self.base_m * (1.0 + 0.15 * wave), WIDTH_MIN_M, WIDTH_MAX_M)


def _sampled(rng: np.random.Generator, features: list[_Feature], straights: np.ndarray,
             width: _Width) -> TrackData:
    """The layout as a measured centre line: spacing, jitter, noise, widths, start."""
    fine_step = 0.25
    xy, spans = _trace(features, straights, fine_step)
    s_fine = np.arange(len(xy)) * fine_step
    lap = len(xy) * fine_step
    spacing = rng.uniform(SPACING_MIN_M, SPACING_MAX_M)
    gaps = spacing * rng.uniform(0.8, 1.2, int(lap / (0.8 * spacing)) + 2)
    s = np.concatenate(([0.0], np.cumsum(gaps)))
    s = s[s < lap - 0.5 * spacing]
    # Start on the longest straight, at most START_BEFORE_END_M before its end.
    longest = int(np.argmax(spans[:, 1] - spans[:, 0]))
    first, last = spans[longest] * fine_step
    s_start = max(first, last - START_BEFORE_END_M)
    s = np.mod(s + s_start, lap)
    x = np.interp(s, s_fine, xy[:, 0], period=lap)
    y = np.interp(s, s_fine, xy[:, 1], period=lap)
    noise = rng.uniform(0.0, NOISE_MAX_M)
    x, y = x + rng.normal(0.0, noise, x.size), y + rng.normal(0.0, noise, y.size)
    total = width(s)
    split = rng.uniform(0.45, 0.55)
    return TrackData(np.round(x, 3), np.round(y, 3), np.round(total * (1.0 - split), 3),
                     np.round(total * split, 3))


def circuit_csv(track: TrackData) -> str:
    """The circuit in the racetrack-database layout (``# x_m,y_m,w_tr_right_m,w_tr_left_m``
    and one row per point), the format :func:`tracker.paths.track_csv.load_track` reads."""
    if track.width_right_m is None or track.width_left_m is None:
        raise ValueError("a circuit without widths has no racetrack-database row")
    rows = ["# x_m,y_m,w_tr_right_m,w_tr_left_m"]
    rows += [f"{x:.3f},{y:.3f},{r:.3f},{left:.3f}" for x, y, r, left in zip(
        track.x_m, track.y_m, track.width_right_m, track.width_left_m, strict=True)]
    return "\n".join(rows) + "\n"
