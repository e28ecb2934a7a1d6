"""The steering commands a filter has been told, as a timeline its predictions run along.

Each command acts on the actuator from its time until the next one's (the controller's
commands are held between control instants, as the plant holds them). A prediction over
``(t0, t1]`` runs piece by piece, split where a command starts inside it
(:meth:`SteeringCommands.pieces`), each piece with the command acting at its start; a
prediction with no command starting inside it is one piece, so a filter told no command at
all predicts exactly as one without a timeline.

The commands are inputs, not the filter's state: restoring an earlier state
(:mod:`estimation.history`, which re-runs the filter after a late measurement) leaves the
timeline as it is, so the re-run meets the commands the first run met. Commands older than
:data:`KEEP_S` behind the newest are dropped (the history reaches back 2 s at most).
"""

from __future__ import annotations

import bisect
import math

from estimation.timing import instant_tolerance_s, is_stale

KEEP_S = 10.0
"""How far behind the newest command the timeline keeps the ones before [s]."""


class SteeringCommands:
    """A timeline of steering commands (module docstring)."""

    def __init__(self) -> None:
        self._times_s: list[float] = []
        self._commands_rad: list[float] = []

    def clear(self) -> None:
        """Forget every command (a new run)."""
        self._times_s.clear()
        self._commands_rad.clear()

    def add(self, t_s: float, steer_rad: float, not_before_s: float = -math.inf) -> None:
        """The command ``steer_rad`` acts from ``t_s`` on (a command at the newest one's
        time replaces it); raises ``ValueError`` for a non-finite value, or a time before
        ``not_before_s`` (the filter's: the past is predicted already) or before the
        newest command's."""
        t_s, steer_rad = float(t_s), float(steer_rad)
        if not (math.isfinite(t_s) and math.isfinite(steer_rad)):
            raise ValueError(f"steering command {steer_rad!r} rad at t_s = {t_s!r}: "
                             "expected finite numbers")
        if is_stale(not_before_s, t_s):
            raise ValueError(f"steering command at t_s = {t_s!r} s: the filter is at "
                             f"{not_before_s!r} s already")
        times = self._times_s
        if times and t_s <= times[-1] + instant_tolerance_s(t_s):
            if t_s < times[-1] - instant_tolerance_s(t_s):
                raise ValueError(f"steering command at t_s = {t_s!r} s: before the last one "
                                 f"({times[-1]!r} s); commands come in time order")
            self._commands_rad[-1] = steer_rad
            return
        times.append(t_s)
        self._commands_rad.append(steer_rad)
        first = bisect.bisect_left(times, t_s - KEEP_S) - 1
        if first > 0:
            del times[:first]
            del self._commands_rad[:first]

    def at(self, t_s: float) -> float | None:
        """The command acting at ``t_s`` (one starting within the clocks' rounding of it
        included); None before the first."""
        i = bisect.bisect_right(self._times_s, t_s + instant_tolerance_s(t_s)) - 1
        return self._commands_rad[i] if i >= 0 else None

    def pieces(self, t0_s: float, t1_s: float,
               interval_s: float) -> list[tuple[float, float | None]]:
        """The prediction from ``t0_s`` to ``t1_s`` (``interval_s`` long, as the filter
        computed it) as pieces ``(duration_s, command)``, split where a command starts
        strictly inside; one piece of ``interval_s`` when none does."""
        times = self._times_s
        start_before_s = t0_s + instant_tolerance_s(t0_s)
        if not times or times[-1] <= start_before_s:  # every command acting from before
            return [(interval_s, self._commands_rad[-1] if times else None)]
        first = bisect.bisect_right(times, start_before_s)
        last = bisect.bisect_left(times, t1_s - instant_tolerance_s(t1_s))
        command = self._commands_rad[first - 1] if first > 0 else None
        if first >= last:
            return [(interval_s, command)]
        pieces: list[tuple[float, float | None]] = []
        start_s = t0_s
        for i in range(first, last):
            pieces.append((times[i] - start_s, command))
            start_s, command = times[i], self._commands_rad[i]
        pieces.append((t1_s - start_s, command))
        return pieces
