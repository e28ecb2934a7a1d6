"""How a run ended: events detected while it goes, and the run's ``outcome``.

Every log period the runner shows the truth (and the tyre loads, when the plant has them) to
an :class:`OutcomeMonitor`. The first time a condition holds, it becomes an :class:`Event`
(kind, simulated time, the value that crossed its threshold), written on ``/events`` and
kept. The thresholds are the ``outcome:`` section of the config (:class:`OutcomeConfig`):

- ``spun``: the car spins out: heading error to the path above ``spin_heading_err_rad``
  (path-tracking runs), or body slip angle ``atan2(v_y, v_x)`` above ``spin_slip_rad``
  at a speed above ``min_speed_mps`` (every run). A car at the limit drives at a few
  degrees of slip; 20 degrees is a spin that a driver could not catch.
- ``rolled_over``: roll angle above ``rollover_roll_rad``, or both wheels of one side
  without load for ``wheel_lift_s`` (a car on two wheels is rolling over, whatever its
  angle); a sedan rolls 3-6 degrees at its grip limit.
- ``off_road``: the centre of gravity further from the path than half ``lane_width_m`` (on
  a track with widths, ``path.kind: track`` or ``generated``: beyond the track's edge)
  (path-tracking runs).
- ``end_of_path``: the car reached the end of an open path with time left (path-tracking
  runs): what follows tracks nothing.
- ``collision``: the ego's body touched a traffic car's (runs with traffic,
  :mod:`cosim.simulation.traffic_loop`); the run ends there, ``completed: false``.

A run stops at the first of the :data:`TERMINAL` events (a spin, a rollover, leaving the
road), ``completed: false`` with the reason, so that its metrics (``cte_max_m`` ...) describe
the run up to the event; ``outcome.keep_going: true`` runs on to the end instead.

The run's ``outcome`` metric is ``ok`` when it completed without events; else the abort
(``interrupted``, ``diverged``, ``error``) or the most severe event's kind, in the order of
:data:`SEVERITY`. Open-loop manoeuvres follow no path, so only slip and roll count there.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from cosim.core.config_fields import setting
from cosim.core.records import VehicleState

OUTCOMES = ("ok", "rolled_over", "spun", "collision", "off_road", "end_of_path",
            "diverged", "interrupted", "error")
"""Every value of the ``outcome`` metric."""

SEVERITY = ("rolled_over", "spun", "collision", "off_road", "end_of_path")
"""Event kinds, most severe first: the outcome of a run with several is the first here."""

WHEEL_SIDES = ((0, 2), (1, 3))
"""Wheel indices (FL, FR, RL, RR order) of the left and the right side."""


@dataclass(frozen=True)
class OutcomeConfig:
    """Thresholds of the run's outcome events (see :mod:`cosim.simulation.outcome`)."""

    spin_heading_err_rad: float = setting(1.0, low=0.0, high=3.1416,
                                          doc="heading error to the path that is a spin")
    spin_slip_rad: float = setting(0.35, low=0.0, high=3.1416,
                                   doc="body slip angle that is a spin (20 deg)")
    min_speed_mps: float = setting(2.0, low=0.0, high=100.0,
                                   doc="slip is judged above this speed only")
    rollover_roll_rad: float = setting(0.6, low=0.0, high=3.1416,
                                       doc="roll angle that is a rollover (34 deg)")
    wheel_lift_s: float = setting(0.5, low=0.0, high=100.0,
                                  doc="both wheels of a side unloaded this long: rollover")
    lane_width_m: float = setting(3.5, low=0.1, high=100.0,
                                  doc="off-road beyond half of it from the path (a track "
                                  "with widths: beyond the track's edge instead)")
    end_margin_m: float = setting(1.0, low=0.0, high=1000.0,
                                  doc="the end of an open path is this close")
    keep_going: bool = setting(False, doc="go on after a spin, a rollover or leaving the "
                               "road (false: the run stops there, so its metrics describe "
                               "the run up to it)")


TERMINAL = ("rolled_over", "spun", "off_road")
"""Events after which a run stops unless ``outcome.keep_going``: nothing after them tells
how well the car was driven."""


@dataclass(frozen=True)
class Event:
    """Something that happened in a run, at simulated time ``t_s``."""

    kind: str
    t_s: float
    value: float
    threshold: float
    detail: str

    def to_message(self) -> dict[str, object]:
        return {"t_s": self.t_s, "kind": self.kind, "value": self.value,
                "threshold": self.threshold, "detail": self.detail}


class OutcomeMonitor:
    """Watches the truth for outcome events; each kind is reported once, when it starts."""

    def __init__(self, config: OutcomeConfig, path_length_m: float | None,
                 tracks_path: bool,
                 road_edges: Callable[[float], tuple[float, float]] | None = None) -> None:
        self.config = config
        self._road_edges = road_edges
        """``s_m -> (left, right)`` half-widths of a track with widths: off the road is the
        centre of gravity beyond the track's edge there, not beyond half a lane."""
        self._path_length_m = path_length_m
        """None for a closed circuit: it has no end."""
        self._tracks_path = tracks_path
        self._lift_since_s: float | None = None
        self.events: list[Event] = []
        self._seen: set[str] = set()

    def _raise(self, kind: str, t_s: float, value: float, threshold: float,
               detail: str) -> Event | None:
        if kind in self._seen:
            return None
        self._seen.add(kind)
        event = Event(kind, t_s, value, threshold, detail)
        self.events.append(event)
        return event

    def observe(self, truth: VehicleState, cte_m: float, heading_err_rad: float, s_m: float,
                wheel_loads_n: tuple[float, ...] | None) -> list[Event]:
        """The events that start at this sample."""
        c, t = self.config, truth.t_s
        found: list[Event | None] = []
        slip = math.atan2(truth.vy_mps, truth.vx_mps)
        if truth.speed_mps > c.min_speed_mps and abs(slip) > c.spin_slip_rad:
            found.append(self._raise("spun", t, abs(slip), c.spin_slip_rad, "body slip angle"))
        if abs(truth.roll_rad) > c.rollover_roll_rad:
            found.append(self._raise("rolled_over", t, abs(truth.roll_rad),
                                     c.rollover_roll_rad, "roll angle"))
        if wheel_loads_n is not None:
            lifted = any(all(wheel_loads_n[i] <= 0.0 for i in side) for side in WHEEL_SIDES)
            if not lifted:
                self._lift_since_s = None
            elif self._lift_since_s is None:
                self._lift_since_s = t
            elif t - self._lift_since_s >= c.wheel_lift_s:
                found.append(self._raise("rolled_over", t, t - self._lift_since_s,
                                         c.wheel_lift_s, "both wheels of one side lifted"))
        if self._tracks_path:
            if abs(heading_err_rad) > c.spin_heading_err_rad:
                found.append(self._raise("spun", t, abs(heading_err_rad),
                                         c.spin_heading_err_rad, "heading error to the path"))
            if self._road_edges is None:
                limit, what = 0.5 * c.lane_width_m, "distance from the path"
            else:
                left, right = self._road_edges(s_m)
                limit = left if cte_m >= 0.0 else right
                what = "distance from the path, beyond the track's edge"
            if abs(cte_m) > limit:
                found.append(self._raise("off_road", t, abs(cte_m), limit, what))
            if self._path_length_m is not None \
                    and s_m >= self._path_length_m - c.end_margin_m:
                found.append(self._raise("end_of_path", t, s_m, self._path_length_m,
                                         "arc length reached the end of the path"))
        return [event for event in found if event is not None]

    def collision(self, t_s: float, car: str) -> Event:
        """Record the collision with traffic car ``car`` at ``t_s`` (it ends the run)."""
        event = Event("collision", t_s, 0.0, 0.0, f"the ego touched traffic car {car!r}")
        self._seen.add("collision")
        self.events.append(event)
        return event

    def outcome(self, abort: str) -> str:
        """``ok``, the abort (``interrupted``, ``diverged``, ``error``; empty: none), or the
        most severe event's kind."""
        if abort:
            return abort
        kinds = {event.kind for event in self.events}
        for kind in SEVERITY:
            if kind in kinds:
                return kind
        return "ok"
