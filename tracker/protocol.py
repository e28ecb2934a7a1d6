"""The interface every path tracker implements, and its optional capabilities.

The runner calls :meth:`Tracker.step` once per control period and nothing else it does not
check for first: a capability is a small protocol of its own that the caller tests with
``isinstance`` (as Gymnasium's wrappers test an environment), never by probing attributes.

It lives with the trackers rather than at the base of ``cosim/`` because its argument, the
:class:`~tracker.paths.reference_path.ReferencePath`, is the trackers' own type.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

from cosim.core.records import Command, Estimate, Plan
from cosim.core.traffic_records import RangeReading
from tracker.paths.reference_path import ReferencePath


@runtime_checkable
class Tracker(Protocol):
    """A path tracker: one control step from the estimate and the reference.

    The contract: ``step`` returns the command to apply at ``t_s`` (it enters the actuator
    delay line) and the plan behind it (a :class:`~cosim.core.records.Plan`; a tracker
    that plans nothing returns a two-node one, as the baselines do). It never sees the
    truth or the plant, only the estimate; a solver failure is a plan with
    ``fallback=True``, not an exception (an exception ends the run as an error).
    """

    def step(
        self, t_s: float, estimate: Estimate, reference: ReferencePath
    ) -> tuple[Command, Plan]: ...


@runtime_checkable
class Resettable(Protocol):
    """A tracker with memory (warm starts, integrators, delay lines) that can forget it."""

    def reset(self) -> None:
        """Forget every previous step, as if newly built."""


@runtime_checkable
class RangeObserver(Protocol):
    """A tracker that reads the forward range sensor (the ACC): the runner hands it every
    reading the sensor samples, before the next control step."""

    def observe_range(self, reading: RangeReading) -> None: ...


@runtime_checkable
class Closable(Protocol):
    """A tracker that holds what must be released after the run (an FMU's instance, its
    library and extracted files: :class:`tracker.fmu.tracker.FmuTracker`); the runner calls
    :meth:`close` once the run has ended, however it ended."""

    def close(self) -> None: ...
