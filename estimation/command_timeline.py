"""The commands a filter has been told, in time order: what its predictions run along.

Each command acts from its time until the next one's (the controller's commands are held
between control instants, as the plant holds them). Commands are told in time order; one
told again at the newest one's instant (within the clocks' rounding) replaces it, and one
from before the filter's own time is refused (the past is predicted already). Commands older
than :data:`KEEP_S` behind the newest are dropped, the one acting then kept (a late
measurement's re-run, :mod:`estimation.history`, reaches back 2 s at most).

The commands are inputs, not the filter's state: restoring an earlier state leaves the
timeline as it is, so a re-run meets the commands the first run met.
:class:`estimation.steering_commands.SteeringCommands` and
:class:`estimation.accel_commands.AccelCommands` are timelines of this kind.
"""

from __future__ import annotations

import bisect
import math

from estimation.timing import instant_tolerance_s, is_stale

KEEP_S = 10.0
"""How far behind the newest command the timeline keeps the ones before [s]."""


class CommandTimeline:
    """Commands (floats) in time order (module docstring)."""

    what = "command"
    """What a command is, for messages ("steering command", ...)."""
    unit = ""
    """Its unit, for messages."""

    def __init__(self) -> None:
        self._times_s: list[float] = []
        self._values: list[float] = []

    def clear(self) -> None:
        """Forget every command (a new run)."""
        self._times_s.clear()
        self._values.clear()

    @property
    def told(self) -> bool:
        """Whether a command has been told since the last :meth:`clear`."""
        return bool(self._times_s)

    def add(self, t_s: float, value: float, not_before_s: float = -math.inf) -> None:
        """The command ``value`` acts from ``t_s`` on (a command at the newest one's time
        replaces it); raises ``ValueError`` for a non-finite value, or a time before
        ``not_before_s`` (the filter's) or before the newest command's."""
        t_s, value = float(t_s), float(value)
        if not (math.isfinite(t_s) and math.isfinite(value)):
            raise ValueError(f"{self.what} {value!r}{self.unit} at t_s = {t_s!r}: expected "
                             "finite numbers")
        if is_stale(not_before_s, t_s):
            raise ValueError(f"{self.what} at t_s = {t_s!r} s: the filter is at "
                             f"{not_before_s!r} s already")
        times = self._times_s
        if times and t_s <= times[-1] + instant_tolerance_s(t_s):
            if t_s < times[-1] - instant_tolerance_s(t_s):
                raise ValueError(f"{self.what} at t_s = {t_s!r} s: before the last one "
                                 f"({times[-1]!r} s); commands come in time order")
            self._values[-1] = value
            return
        self._appending(t_s)
        times.append(t_s)
        self._values.append(value)
        first = bisect.bisect_left(times, t_s - KEEP_S) - 1
        if first > 0:
            del times[:first]
            del self._values[:first]
            self._dropped(first)

    def _appending(self, t_s: float) -> None:
        """A new command at ``t_s`` is about to be appended (for what a subclass keeps
        beside each command)."""

    def _dropped(self, count: int) -> None:
        """The ``count`` oldest commands were dropped."""
