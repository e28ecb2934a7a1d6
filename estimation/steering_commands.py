"""The steering commands a filter has been told, as a timeline its predictions run along.

Each command acts on the actuator from its time until the next one's (the controller's
commands are held between control instants, as the plant holds them). A prediction over
``(t0, t1]`` runs piece by piece, split where a command starts inside it
(:meth:`SteeringCommands.pieces`), each piece with the command acting at its start; a
prediction with no command starting inside it is one piece, so a filter told no command at
all predicts exactly as one without a timeline.

The commands are inputs, not the filter's state (:mod:`estimation.command_timeline`: the
order, the replacing and the dropping they share with the acceleration commands).
"""

from __future__ import annotations

import bisect

from estimation.command_timeline import CommandTimeline
from estimation.timing import instant_tolerance_s


class SteeringCommands(CommandTimeline):
    """A timeline of steering commands (module docstring)."""

    what = "steering command"
    unit = " rad"

    def at(self, t_s: float) -> float | None:
        """The command acting at ``t_s`` (one starting within the clocks' rounding of it
        included); None before the first."""
        i = bisect.bisect_right(self._times_s, t_s + instant_tolerance_s(t_s)) - 1
        return self._values[i] if i >= 0 else None

    def pieces(self, t0_s: float, t1_s: float,
               interval_s: float) -> list[tuple[float, float | None]]:
        """The prediction from ``t0_s`` to ``t1_s`` (``interval_s`` long, as the filter
        computed it) as pieces ``(duration_s, command)``, split where a command starts
        strictly inside; one piece of ``interval_s`` when none does."""
        times = self._times_s
        start_before_s = t0_s + instant_tolerance_s(t0_s)
        if not times or times[-1] <= start_before_s:  # every command acting from before
            return [(interval_s, self._values[-1] if times else None)]
        first = bisect.bisect_right(times, start_before_s)
        last = bisect.bisect_left(times, t1_s - instant_tolerance_s(t1_s))
        command = self._values[first - 1] if first > 0 else None
        if first >= last:
            return [(interval_s, command)]
        pieces: list[tuple[float, float | None]] = []
        start_s = t0_s
        for i in range(first, last):
            pieces.append((times[i] - start_s, command))
            start_s, command = times[i], self._values[i]
        pieces.append((t1_s - start_s, command))
        return pieces
