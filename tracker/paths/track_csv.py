"""A circuit's centre line from CSV: the racetrack-database layout or plain ``x,y``.

The open race-track collections used in autonomous racing (TUM's racetrack-database, after
Heilmeier et al., Vehicle System Dynamics 58(10), 2020) store one closed circuit per file:
a ``#`` comment header ``# x_m,y_m,w_tr_right_m,w_tr_left_m`` and one centre-line point per
row with the track's half-widths to the right and left. The loop is implicit (the last row
does not repeat the first). A plain file has two columns ``x,y`` (an optional header line
of names without ``#``) and no widths.

Refused with one line naming the file and what was expected: missing columns, fewer than
three points, non-finite numbers, two consecutive points at the same place. A centre line
that crosses itself is accepted with a warning (a figure eight is legal; a circuit that
does is usually a mistake).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cosim.core.exceptions import ConfigError

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


def _rows(path: Path) -> tuple[list[str], list[list[str]]]:
    try:
        text = path.read_text()
    except OSError as error:
        raise ConfigError(f"path.file {str(path)!r}: cannot read ({error.strerror})") from None
    header: list[str] = []
    rows = []
    for line in text.splitlines():
        stripped = line.strip()
        if not stripped:
            continue
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


def load_track(path: str | Path) -> TrackData:
    """Read a centre line (and widths) from ``path``; see the module docstring."""
    path = Path(path)
    name = f"path.file {str(path)!r}"
    header, rows = _rows(path)
    racetrack = [h for h in header if h in RACETRACK_COLUMNS]
    columns = 4 if len(racetrack) == 4 or (not header and rows and len(rows[0]) >= 4) else 2
    if header and racetrack and len(racetrack) < 4:
        missing = [c for c in RACETRACK_COLUMNS if c not in header]
        raise ConfigError(f"{name}: missing column(s) {', '.join(missing)} (expected "
                          f"{', '.join(RACETRACK_COLUMNS)})")
    values = []
    for number, cells in enumerate(rows, start=1):
        if len(cells) < columns:
            expected = ", ".join(RACETRACK_COLUMNS) if columns == 4 else "x, y"
            raise ConfigError(f"{name}: data row {number} has {len(cells)} column(s), "
                              f"expected {columns} ({expected})")
        try:
            values.append([float(c) for c in cells[:columns]])
        except ValueError:
            raise ConfigError(f"{name}: data row {number} = {','.join(cells)!r}: expected "
                              "numbers") from None
    data = np.asarray(values, dtype=float).reshape(-1, columns)
    if len(data) and np.allclose(data[0, :2], data[-1, :2]):
        data = data[:-1]  # a file that repeats its first point to close the loop
    if len(data) < 3:
        raise ConfigError(f"{name}: {len(data)} point(s), expected at least 3")
    bad = np.flatnonzero(~np.all(np.isfinite(data), axis=1))
    if bad.size:
        raise ConfigError(f"{name}: data row {bad[0] + 1} is not finite (NaN or inf), "
                          "expected finite numbers")
    step = np.hypot(np.diff(data[:, 0]), np.diff(data[:, 1]))
    same = np.flatnonzero(step <= 1e-9)
    if same.size:
        raise ConfigError(f"{name}: data rows {same[0] + 1} and {same[0] + 2} are the same "
                          "point, expected distinct consecutive points")
    if columns == 4 and np.any(data[:, 2:] <= 0.0):
        row = int(np.flatnonzero(np.any(data[:, 2:] <= 0.0, axis=1))[0]) + 1
        raise ConfigError(f"{name}: data row {row} has a track width <= 0, expected > 0")
    crossing = first_self_intersection(data[:, 0], data[:, 1])
    if crossing is not None:
        warnings.warn(f"{name}: the centre line crosses itself near segment {crossing + 1}",
                      SelfIntersectionWarning, stacklevel=2)
    return TrackData(data[:, 0].copy(), data[:, 1].copy(),
                     data[:, 2].copy() if columns == 4 else None,
                     data[:, 3].copy() if columns == 4 else None)


def first_self_intersection(x_m: np.ndarray, y_m: np.ndarray) -> int | None:
    """Index of the first segment of the closed polygon that properly crosses another
    (neighbours sharing an end point do not count); None for a simple loop."""
    p = np.column_stack((x_m, y_m))
    q = np.roll(p, -1, axis=0)
    n = len(p)
    for i in range(n):
        a, b = p[i], q[i]
        j = np.arange(i + 2, n)
        if i == 0:
            j = j[j != n - 1]
        if not j.size:
            continue
        c, d = p[j], q[j]

        def cross(o: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
            return (u[..., 0] - o[..., 0]) * (v[..., 1] - o[..., 1]) - \
                (u[..., 1] - o[..., 1]) * (v[..., 0] - o[..., 0])

        d1, d2 = cross(c, d, a), cross(c, d, b)
        d3, d4 = cross(a, b, c), cross(a, b, d)
        if np.any((d1 * d2 < 0) & (d3 * d4 < 0)):
            return i
    return None
