"""A circuit's centre line from CSV: the racetrack-database layout or plain ``x,y``.

The open race-track collections used in autonomous racing (TUM's racetrack-database, after
Heilmeier et al., Vehicle System Dynamics 58(10), 2020) store one closed circuit per file:
a ``#`` comment header ``# x_m,y_m,w_tr_right_m,w_tr_left_m`` and one centre-line point per
row with the track's half-widths to the right and left. The loop is implicit (the last row
does not repeat the first). A plain file has two columns ``x,y`` (an optional header line
of names without ``#``) and no widths.

Refused with one line naming the file and what was expected: anything but a regular file
(``/dev/zero`` would be read for ever), a file above :data:`MAX_FILE_BYTES`, text that is
not UTF-8 (a byte-order mark is dropped; ``\r\n`` line ends are fine), missing columns,
fewer than three distinct points, non-finite numbers, coordinates beyond
:data:`MAX_COORDINATE_M` or a centre line longer than :data:`MAX_LENGTH_M` (coordinates in
millimetres, or scaled by mistake), two consecutive points at the same place, a turn back
on itself (:data:`MAX_TURN_DEG`), and a circuit (``path.closed``, the default) whose last
point is far from its first: an open path must say ``path.closed: false``. A centre line
that crosses itself is accepted with a warning (a figure eight is legal; a circuit that
does is usually a mistake), and so is one whose points lie more than
:data:`MAX_SPACING_M` apart (coordinates in centimetres read as metres). A header that
names a column cosim would not read (a single ``width``) is refused rather than dropped,
and so is a file whose columns are separated by semicolons or tabs. Every check is linear
in the point count but the crossing test, which is O(n log n)
(:func:`first_self_intersection`).
"""

from __future__ import annotations

import stat
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cosim.core.exceptions import ConfigError
from cosim.core.yaml_io import shown

RACETRACK_COLUMNS = ("x_m", "y_m", "w_tr_right_m", "w_tr_left_m")
"""The racetrack-database columns, in order."""


@dataclass(frozen=True)
class TrackData:
    """A centre line and, when the file has them, the half-widths to each side [m]."""

    x_m: np.ndarray
    y_m: np.ndarray
    width_right_m: np.ndarray | None
    width_left_m: np.ndarray | None


class SelfIntersectionWarning(UserWarning):
    """The centre line crosses itself."""


class TrackScaleWarning(UserWarning):
    """The centre line's points are far apart: its unit may not be metres."""


MAX_SPACING_M = 50.0
"""A median point spacing above this is said (centimetres read as metres give ~100 m)."""


MAX_FILE_BYTES = 64 * 1024 * 1024
"""A circuit file larger than this is refused (a 200 000-point racetrack file is ~8 MB)."""

MAX_COORDINATE_M = 1e7
"""Largest coordinate accepted: projected coordinates (UTM northings reach 1e7 m)."""

MAX_LENGTH_M = 1e5
"""Longest centre line accepted (``path.length_m``'s bound): a lap of the Nordschleife is
21 km; beyond this the projection table alone would take hundreds of megabytes."""

MAX_WIDTH_M = 100.0
"""Largest half-width accepted (``path.default_width_m``'s bound)."""

MAX_TURN_DEG = 150.0
"""A path whose heading changes by more than this within :data:`TURN_WINDOW_M` (or from
one segment to the next) goes back on itself: refused. A car's tightest turn (a radius of
about 5 m) turns by at most 60 deg within 5 m."""

TURN_WINDOW_M = 5.0
"""Arc length over which a turn back is looked for."""

OPEN_GAP_SPACINGS = 10.0
"""A closed circuit whose last point is further from its first than this many times the
median point spacing (and 10 m) is taken to be an open path: refused unless path.closed is
false."""


def _text(path: Path, name: str) -> str:
    """The file's text: a regular file of at most :data:`MAX_FILE_BYTES`, UTF-8 with or
    without a byte-order mark."""
    try:
        status = path.stat()
    except OSError as error:
        raise ConfigError(f"{name}: cannot read ({error.strerror})") from None
    if not stat.S_ISREG(status.st_mode):
        raise ConfigError(f"{name}: not a regular file (a device, pipe or folder): expected "
                          "a CSV file")
    if status.st_size > MAX_FILE_BYTES:
        raise ConfigError(f"{name}: {status.st_size:,} bytes: expected a circuit file of at "
                          f"most {MAX_FILE_BYTES:,} bytes")
    try:
        with path.open("rb") as stream:
            data = stream.read(MAX_FILE_BYTES + 1)
    except OSError as error:
        raise ConfigError(f"{name}: cannot read ({error.strerror})") from None
    if len(data) > MAX_FILE_BYTES:  # it grew since the stat
        raise ConfigError(f"{name}: more than {MAX_FILE_BYTES:,} bytes: expected a circuit "
                          "file of at most that")
    try:
        return data.decode("utf-8-sig")  # a byte-order mark is dropped, not read as data
    except UnicodeDecodeError as error:
        raise ConfigError(f"{name}: byte {error.start} is not UTF-8: expected a UTF-8 text "
                          "file") from None


def _rows(path: Path, name: str) -> tuple[list[str], list[list[str]]]:
    header: list[str] = []
    rows = []
    for line in _text(path, name).splitlines():  # \n, \r\n and \r alike
        stripped = line.strip()
        if not stripped:
            continue
        if "," not in stripped and not stripped.startswith("#"):
            for other, called in ((";", "semicolons"), ("\t", "tabs")):
                if other in stripped:
                    raise ConfigError(f"{name}: columns separated by {called} "
                                      f"({shown(stripped[:40])}): expected commas (x,y)")
        if stripped.startswith("#"):
            if not header and not rows:
                header = [c.strip() for c in stripped.lstrip("#").split(",")]
            continue
        cells = [c.strip() for c in stripped.split(",")]
        if not rows and not header and not _is_number(cells[0]):
            header = cells
            continue
        rows.append(cells)
    return header, rows


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def load_track(path: str | Path, closed: bool = True) -> TrackData:
    """Read a centre line (and widths) from ``path``; see the module docstring. ``closed``:
    the file is a circuit (``path.closed``), checked against where it ends."""
    path = Path(path)
    name = f"path.file {str(path)!r}"
    header, rows = _rows(path, name)
    _check_header(header, rows, name)
    racetrack = [h for h in header if h in RACETRACK_COLUMNS]
    columns = 4 if len(racetrack) == 4 or (not header and rows and len(rows[0]) >= 4) else 2
    if header[:2] == ["x_m", "y_m"] and len(header) == 2:
        racetrack = []  # plain x, y in metres
    if header and racetrack and len(racetrack) < 4:
        missing = [c for c in RACETRACK_COLUMNS if c not in header]
        raise ConfigError(f"{name}: missing column(s) {', '.join(missing)} (expected "
                          f"{', '.join(RACETRACK_COLUMNS)})")
    data = _numbers(rows, columns, name)
    if len(data) > 1 and np.allclose(data[0, :2], data[-1, :2]):
        data = data[:-1]  # a file that repeats its first point to close the loop
    _check_values(data, columns, name)
    _check_course(data[:, 0], data[:, 1], closed, name)
    crossing = first_self_intersection(data[:, 0], data[:, 1], closed)
    if crossing is not None:
        warnings.warn(f"{name}: the centre line crosses itself near segment {crossing + 1}",
                      SelfIntersectionWarning, stacklevel=2)
    return TrackData(data[:, 0].copy(), data[:, 1].copy(),
                     data[:, 2].copy() if columns == 4 else None,
                     data[:, 3].copy() if columns == 4 else None)


PLAIN_HEADERS = (["x", "y"], ["x_m", "y_m"])
"""Headers of a plain centre line (no widths)."""


def _check_header(header: list[str], rows: list[list[str]], name: str) -> None:
    """Refuse columns cosim would not read (a single ``width``, a third unnamed column):
    dropping them silently would lose the track's limits."""
    expected = ("expected x,y (or x_m,y_m) for a centre line alone, or "
                f"{','.join(RACETRACK_COLUMNS)} for one with its half-widths")
    if header and header not in PLAIN_HEADERS and not set(RACETRACK_COLUMNS) <= set(header) \
            and not any(h in RACETRACK_COLUMNS[2:] for h in header):
        unread = [h for h in header if h not in ("x", "y", "x_m", "y_m")]
        if unread:
            raise ConfigError(f"{name}: column(s) {', '.join(unread)} would not be read: "
                              f"{expected} (a full track width w: w/2 in each)")
    if not header and rows and len(rows[0]) == 3:
        raise ConfigError(f"{name}: 3 columns and no header: {expected}")


def _numbers(rows: list[list[str]], columns: int, name: str) -> np.ndarray:
    values = []
    for number, cells in enumerate(rows, start=1):
        if len(cells) < columns:
            expected = ", ".join(RACETRACK_COLUMNS) if columns == 4 else "x, y"
            raise ConfigError(f"{name}: data row {number} has {len(cells)} column(s), "
                              f"expected {columns} ({expected})")
        try:
            values.append([float(c) for c in cells[:columns]])
        except ValueError:
            raise ConfigError(f"{name}: data row {number} = {shown(','.join(cells))}: "
                              "expected numbers") from None
    return np.asarray(values, dtype=float).reshape(-1, columns)


def _check_values(data: np.ndarray, columns: int, name: str) -> None:
    """At least 3 distinct points, finite and within bounds, the widths positive."""
    distinct = len(np.unique(data[:, :2], axis=0)) if len(data) else 0
    if distinct < 3:
        raise ConfigError(f"{name}: {distinct} distinct point(s), expected at least 3")
    bad = np.flatnonzero(~np.all(np.isfinite(data), axis=1))
    if bad.size:
        raise ConfigError(f"{name}: data row {bad[0] + 1} is not finite (NaN or inf), "
                          "expected finite numbers")
    far = np.flatnonzero(np.any(np.abs(data[:, :2]) > MAX_COORDINATE_M, axis=1))
    if far.size:
        raise ConfigError(f"{name}: data row {far[0] + 1} has a coordinate beyond "
                          f"{MAX_COORDINATE_M:g} m: expected metres (|x|, |y| <= "
                          f"{MAX_COORDINATE_M:g})")
    step = np.hypot(np.diff(data[:, 0]), np.diff(data[:, 1]))
    same = np.flatnonzero(step <= 1e-9)
    if same.size:
        raise ConfigError(f"{name}: data rows {same[0] + 1} and {same[0] + 2} are the same "
                          "point, expected distinct consecutive points")
    if step.sum() > MAX_LENGTH_M:
        raise ConfigError(f"{name}: the centre line is {step.sum():,.0f} m long: expected at "
                          f"most {MAX_LENGTH_M:,.0f} m (are the coordinates in metres?)")
    if columns == 4:
        widths = data[:, 2:]
        row = np.flatnonzero(np.any((widths <= 0.0) | (widths > MAX_WIDTH_M), axis=1))
        if row.size:
            raise ConfigError(f"{name}: data row {row[0] + 1} has a track width <= 0 or above "
                              f"{MAX_WIDTH_M:g} m, expected > 0 and at most {MAX_WIDTH_M:g}")


def _check_course(x_m: np.ndarray, y_m: np.ndarray, closed: bool, name: str) -> None:
    """A circuit that ends where it starts (when ``closed``); no turn back on itself."""
    step = np.hypot(np.diff(x_m), np.diff(y_m))
    gap = float(np.hypot(x_m[-1] - x_m[0], y_m[-1] - y_m[0]))
    spacing = float(np.median(step))
    if spacing > MAX_SPACING_M:
        warnings.warn(f"{name}: its points are {spacing:.3g} m apart (median) on a "
                      f"{float(step.sum()) / 1000.0:.3g} km centre line: are the coordinates "
                      "in metres? (a circuit's centre line is usually a point every 1-10 m; "
                      "centimetres would make it 100 times too large)", TrackScaleWarning,
                      stacklevel=3)
    if closed and gap > max(OPEN_GAP_SPACINGS * spacing, 10.0):
        raise ConfigError(f"{name}: its last point is {gap:.1f} m from its first (the points "
                          f"are {spacing:.2g} m apart): expected a closed circuit, as "
                          "path.closed = true says; set path.closed=false for an open path")
    px, py = (np.append(x_m, x_m[0]), np.append(y_m, y_m[0])) if closed else (x_m, y_m)
    heading = np.arctan2(np.diff(py), np.diff(px))
    length = np.hypot(np.diff(px), np.diff(py))
    start = np.concatenate(([0.0], np.cumsum(length)[:-1]))
    segments = np.arange(heading.size)
    for ahead_m in (0.0, TURN_WINDOW_M / 2.0, TURN_WINDOW_M):
        target = start + length + ahead_m  # the segment after, and points further on
        if closed:
            target = np.mod(target, float(length.sum()))
        later = np.searchsorted(start, target, side="right") - 1
        if not closed:
            later = np.minimum(later, heading.size - 1)
        turn = np.degrees(np.abs(np.angle(np.exp(1j * (heading[later] - heading)))))
        back = np.flatnonzero((turn > MAX_TURN_DEG) & (later != segments))
        if back.size:
            k = int(back[0])
            raise ConfigError(
                f"{name}: the path turns back by {turn[k]:.0f} deg between data rows "
                f"{k + 1} and {later[k] % len(x_m) + 2}: expected a path that goes on (at "
                f"most {MAX_TURN_DEG:g} deg within {TURN_WINDOW_M:g} m)")


def first_self_intersection(x_m: np.ndarray, y_m: np.ndarray,
                            closed: bool = True) -> int | None:
    """Index of the first segment of the polygon (closed: with the segment from the last
    point back to the first) that properly crosses another (neighbours sharing an end point
    do not count); None for a simple one.

    O(n log n) for evenly spaced points: only segments whose midpoints lie within one
    segment length of each other can cross, and a k-d tree (scipy's ``cKDTree``) finds
    those pairs; the few segments much longer than the rest are tested against all.
    """
    p = np.column_stack((x_m, y_m))
    q = np.roll(p, -1, axis=0)
    n = len(p)
    segments = n if closed else n - 1
    p, q = p[:segments], q[:segments]
    length = np.hypot(*(q - p).T)
    reach = 4.0 * float(np.median(length))
    long = np.flatnonzero(length > reach)
    from scipy.spatial import cKDTree  # here: heavy, and for track files only

    pairs = cKDTree((p + q) / 2.0).query_pairs(reach, output_type="ndarray")
    if long.size:
        every = np.arange(segments)
        pairs = np.vstack([pairs, *(np.column_stack((np.full(segments, i), every))
                                    for i in long)])
    i, j = np.minimum(pairs[:, 0], pairs[:, 1]), np.maximum(pairs[:, 0], pairs[:, 1])
    keep = (j - i > 1) & ~(closed & (i == 0) & (j == n - 1))
    i, j = i[keep], j[keep]
    a, b, c, d = p[i], q[i], p[j], q[j]

    def cross(o: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        return (u[:, 0] - o[:, 0]) * (v[:, 1] - o[:, 1]) - (u[:, 1] - o[:, 1]) * (v[:, 0] - o[:, 0])

    hit = (cross(c, d, a) * cross(c, d, b) < 0) & (cross(a, b, c) * cross(a, b, d) < 0)
    return int(i[hit].min()) if np.any(hit) else None
