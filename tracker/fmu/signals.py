"""What cosim hands an FMU tracker and what it reads back: the signals, by variable name.

One table (:data:`INPUTS`, :data:`OUTPUTS`) says for every FMU variable name what it is, its
unit and how it is computed; an FMU declares the inputs it reads and cosim serves exactly
those. Every input comes from the filter's estimate and the reference (the tracker's whole
view: never the truth). Signs are ISO 8855 and ENU (x forward, y left, yaw counter-clockwise
positive, steering positive to the left, a cross-track error positive when the car is left
of the path). The unit of a name is the one its suffix implies (``cte_m`` in m,
``heading_err_rad`` in rad: :func:`cosim.core.config_fields.unit_of`).

The estimate is projected onto the path (:meth:`ReferencePath.project`, searched near the
previous projection so that a path passing near itself cannot make it jump); with ``p`` the
estimated CoG, ``psi`` the estimated yaw and ``s`` the projection's arc length:

- ``cte_m = n(s) . (p - c(s))``, ``n`` the path's left normal, ``c`` the path point;
- ``heading_err_rad = wrap(psi - psi_path(s))``;
- preview point ``i`` (``i = 1 .. N``, the indices the FMU declares) is ``c(s + i d)`` with
  ``d = tracker.fmu.preview_spacing_m``, turned into the vehicle frame:
  ``x_v = cos(psi) dx + sin(psi) dy``, ``y_v = -sin(psi) dx + cos(psi) dy`` with
  ``(dx, dy) = c(s + i d) - p``. On a closed path the arc length wraps; an open path's
  points stop at its end.

The names of scalars taken from an array follow the FMI structured naming convention
(``preview_x_m[1]``; FMI 2.0.4, section 2.2.9).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

from cosim.core.config_fields import unit_of
from cosim.core.records import Estimate
from tracker.paths.reference_path import ReferencePath, wrap_angle


@dataclass(frozen=True)
class Signal:
    """One FMU variable cosim knows: its name, its unit and how cosim computes or uses it."""

    name: str
    """The variable's name; ``[i]`` stands for a preview index, ``<state>`` for a state."""
    unit: str
    """The unit its name implies (cosim's spelling: ``m/s^2``)."""
    meaning: str


PATH_SIGNALS: tuple[Signal, ...] = (
    Signal("cte_m", "m", "signed distance of the estimated CoG from its projection on the "
           "reference path, positive when the car is left of the path"),
    Signal("heading_err_rad", "rad", "estimated yaw minus the path's yaw at the projection, "
           "wrapped to (-pi, pi]"),
    Signal("speed_mps", "m/s", "estimated speed over ground, hypot(vx, vy)"),
    Signal("ref_speed_mps", "m/s", "reference speed at the projection's arc length, now"),
    Signal("curvature_1pm", "1/m", "the path's curvature at the projection, positive to the "
           "left"),
    Signal("path_s_m", "m", "arc length of the projection along the path"),
)
"""Inputs from the estimate projected on the reference."""

STATE_PREFIX = "est_"
"""``est_<state>`` is the estimate's mean of ``<state>`` (``est_vx_mps``, ``est_steer_rad``)."""

PREVIEW_SIGNALS: tuple[Signal, ...] = (
    Signal("preview_x_m[i]", "m", "reference point i * tracker.fmu.preview_spacing_m ahead "
           "of the projection, vehicle frame: forward"),
    Signal("preview_y_m[i]", "m", "the same point, vehicle frame: to the left"),
)
"""Inputs: the reference ahead, as many points as the FMU declares."""

INPUTS: tuple[Signal, ...] = (
    *PATH_SIGNALS,
    Signal(STATE_PREFIX + "<state>", "the state's", "the estimate's mean of one of the "
           "estimator's states, e.g. est_x_m, est_yaw_rad, est_vx_mps, est_yaw_rate_radps, "
           "est_steer_rad (ekf and ukf: the states of estimation.state.STATE_NAMES)"),
    *PREVIEW_SIGNALS,
)
"""Every input an FMU may declare."""

OUTPUTS: tuple[Signal, ...] = (
    Signal("steer_rad", "rad", "road-wheel steering angle, positive to the left; clipped to "
           "+-tracker.max_steer_rad"),
    Signal("accel_mps2", "m/s^2", "longitudinal acceleration demand; clipped to "
           "[tracker.accel_min_mps2, tracker.accel_max_mps2]"),
)
"""What cosim reads back after each step (both required)."""

_PREVIEW = re.compile(r"^preview_([xy])_m\[(\d+)\]$")


@dataclass(frozen=True)
class InputRef:
    """What one FMU input name refers to."""

    kind: str
    """``path`` (a :data:`PATH_SIGNALS` name), ``state``, ``preview_x`` or ``preview_y``."""
    key: str = ""
    """The path signal's or the state's name."""
    index: int = 0
    """The preview index (1-based)."""


def parse_input(name: str) -> InputRef | None:
    """What the input ``name`` refers to, or None if cosim serves no such signal."""
    if name in {s.name for s in PATH_SIGNALS}:
        return InputRef("path", name)
    if name.startswith(STATE_PREFIX) and len(name) > len(STATE_PREFIX):
        return InputRef("state", name.removeprefix(STATE_PREFIX))
    match = _PREVIEW.match(name)
    if match:
        return InputRef(f"preview_{match[1]}", index=int(match[2]))
    return None


def implied_unit(name: str) -> str:
    """The unit the variable name implies (``-`` when it names none): its suffix, array
    subscript removed (``preview_x_m[3]`` -> ``m``)."""
    return unit_of(name.split("[", 1)[0])


class InputFeed:
    """Computes the values of an FMU's inputs, in the order of its input list."""

    def __init__(self, names: tuple[str, ...], preview_spacing_m: float) -> None:
        refs = [parse_input(name) for name in names]
        if any(ref is None for ref in refs):
            raise ValueError("InputFeed: every name must be a signal (checked before)")
        self.names = names
        self._refs: tuple[InputRef, ...] = tuple(r for r in refs if r is not None)
        indices = sorted({r.index for r in self._refs if r.kind.startswith("preview")})
        self._preview_index = {index: i for i, index in enumerate(indices)}
        self._preview_s_m = np.asarray(indices, dtype=float) * preview_spacing_m
        self._near_s_m: float | None = None

    def reset(self) -> None:
        """Forget the last projection (a new run)."""
        self._near_s_m = None

    def values(self, t_s: float, estimate: Estimate, reference: ReferencePath) -> list[float]:
        """Every input's value at ``t_s`` (module docstring), in the order of ``names``."""
        x, y, yaw = estimate["x_m"], estimate["y_m"], estimate["yaw_rad"]
        projection = reference.project(x, y, self._near_s_m)
        self._near_s_m = projection.s_m
        vy = estimate["vy_mps"] if "vy_mps" in estimate else 0.0
        path = {
            "cte_m": projection.lateral_error_m,
            "heading_err_rad": float(wrap_angle(yaw - projection.path_yaw_rad)),
            "speed_mps": math.hypot(estimate["vx_mps"], vy),
            "ref_speed_mps": reference.speed_ref_at(projection.s_m, t_s),
            "curvature_1pm": projection.curvature_1pm,
            "path_s_m": projection.s_m,
        }
        preview_x, preview_y = self._preview(projection.s_m, x, y, yaw, reference)
        out = []
        for ref in self._refs:
            if ref.kind == "path":
                out.append(path[ref.key])
            elif ref.kind == "state":
                out.append(estimate[ref.key])
            elif ref.kind == "preview_x":
                out.append(preview_x[self._preview_index[ref.index]])
            else:
                out.append(preview_y[self._preview_index[ref.index]])
        return out

    def _preview(self, s_m: float, x_m: float, y_m: float, yaw_rad: float,
                 reference: ReferencePath) -> tuple[list[float], list[float]]:
        """The preview points in the vehicle frame (module docstring)."""
        if not self._preview_s_m.size:
            return [], []
        points = reference.sample(s_m + self._preview_s_m)
        dx, dy = points["x_m"] - x_m, points["y_m"] - y_m
        cos, sin = math.cos(yaw_rad), math.sin(yaw_rad)
        return (cos * dx + sin * dy).tolist(), (-sin * dx + cos * dy).tolist()


def markdown_table() -> str:
    """The signal table as Markdown, as docs/fmu.md shows it (a test keeps them equal)."""
    rows = ["| role | name | unit | meaning |", "|---|---|---|---|"]
    rows += [f"| {role} | `{s.name}` | {s.unit} | {s.meaning} |"
             for role, signals in (("input", INPUTS), ("output", OUTPUTS)) for s in signals]
    return "\n".join(rows) + "\n"
