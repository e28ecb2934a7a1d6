"""The interface every path tracker implements (the runner calls nothing else).

It lives with the trackers rather than at the base of ``cosim/`` because its argument, the
:class:`~tracker.paths.reference_path.ReferencePath`, is the trackers' own type.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

from cosim.core.records import Command, Estimate, Plan
from tracker.paths.reference_path import ReferencePath


class Tracker(Protocol):
    """A path tracker: one control step from the estimate and the reference."""

    def step(
        self, t_s: float, estimate: Estimate, reference: ReferencePath
    ) -> tuple[Command, Plan]: ...


@runtime_checkable
class Closable(Protocol):
    """A tracker that holds what must be released after the run (an FMU's instance, its
    library and extracted files: :class:`tracker.fmu.tracker.FmuTracker`); the runner calls
    :meth:`close` once the run has ended, however it ended."""

    def close(self) -> None: ...
