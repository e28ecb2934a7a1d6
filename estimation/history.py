"""Late measurements fused at their own time: a short history of the filter, re-run.

A receiver's fix reaches the filter some time after the instant it was measured (GNSS
receivers report 50-200 ms late: the solution's computation and the serial link); by then
the filter has predicted past that instant and fused the IMU, wheel speeds and steering
that came since. Fusing the fix at the arrival time would treat an old position as the
present one (at 20 m/s, 150 ms is 3 m); refusing it as stale wastes it. Here the filter
keeps its recent history and fuses the fix where it belongs, re-running what came after
("re-processing" of an out-of-sequence measurement, Bar-Shalom, "Update with
out-of-sequence measurements in tracking: exact solution", IEEE Trans. AES 38(3), 2002,
whose exact single-lag solution it is for a linearised model, computed by replay):

1. every call that changes the filter (a prediction the loop asks for, the measurements of
   one instant) is kept as an :class:`Event` with the filter's state just before it
   (:class:`FilterState`: belief, time, counters, gate timers);
2. a measurement older than the filter's time (or of the instant the filter has just
   fused) restores the state before the first event after it, joins the measurements of
   its own instant (or becomes an event of its own there) and every later event runs
   again, in order, with the same arguments.

The filter after the late measurement is then the one that would have had it on time
(the same predictions, the same updates, only the late one added), bit for bit when its
instant's update is the joint one (whose result does not depend on the order of the
measurements). Events older than ``history_s`` are dropped; a measurement older than the
history is rejected as stale, as a filter without history rejects every late one.

Cost: each late measurement re-runs ``latency / step`` instants (GNSS 150 ms late at
10 Hz against 100 Hz instants: 15 instants, about 1.5 ms, 10 times a second).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from cosim.core.initial_state import InitialState
from cosim.core.records import Estimate, Measurement
from estimation.timing import is_stale
from estimation.update_result import SensorCounts, UpdateResult


class FilterState(Protocol):
    """What a filter's :meth:`Replayable.state` returns: opaque to the history, restored
    whole by :meth:`Replayable.restore`; its ``t_s`` is the belief's time."""

    @property
    def t_s(self) -> float: ...


class Replayable(Protocol):
    """A filter whose whole state can be taken and put back (the built-in filters), with
    the calls the runner makes (:mod:`estimation.protocol`)."""

    required_sensors: tuple[str, ...]
    supported_sensors: tuple[str, ...]

    @property
    def t_s(self) -> float: ...

    def state(self) -> FilterState:
        """Everything that changes as the filter runs (a copy: later steps do not alter it)."""

    def restore(self, state: FilterState) -> None:
        """Put back a :meth:`state`: the filter continues as it would have from there."""

    def predict(self, t_s: float) -> None: ...

    def update_many(self, measurements: Sequence[Measurement]) -> list[UpdateResult]: ...

    def command(self, t_s: float, steer_rad: float) -> None: ...

    def accel_command(self, t_s: float, accel_mps2: float) -> None: ...

    def estimate(self) -> Estimate: ...

    def estimate_at(self, t_s: float) -> Estimate: ...

    def counts(self) -> dict[str, dict[str, int]]: ...

    def restart(self, initial: InitialState, *, t0_s: float = 0.0,
                rng: np.random.Generator | None = None) -> None: ...


@dataclass(frozen=True)
class FusionState:
    """The state of a Kalman filter of :mod:`estimation.fusion` (:meth:`Replayable.state`):
    its belief at ``t_s``, its per-sensor counters and gate timers, and whether it still
    waits for its first fix."""

    t_s: float
    mean: np.ndarray
    covariance: np.ndarray
    counts: dict[str, SensorCounts]
    gate_failing_since_s: dict[tuple[str, tuple[str, ...]], float]
    awaiting_first_fix: bool


@dataclass(frozen=True)
class Lookahead:
    """A prediction :meth:`estimation.fusion.KalmanFusion.estimate_at` made for an observer
    and undid: from the belief ``before`` (the very arrays, at ``t0_s``) to
    ``mean``/``covariance`` at ``t_s``. The log looks at the instants the sensors report,
    just before the filter itself predicts to them from the same belief: that prediction
    is this one."""

    before: tuple[np.ndarray, np.ndarray]
    t0_s: float
    t_s: float
    mean: np.ndarray
    covariance: np.ndarray


@dataclass
class Event:
    """One call that changed the filter: a prediction to ``t_s`` (``measurements`` None) or
    the measurements of instant ``t_s``; ``before`` is the filter's state before it."""

    t_s: float
    measurements: list[Measurement] | None
    before: FilterState


@dataclass
class History:
    """The events of the last ``history_s`` seconds of one filter (module docstring)."""

    history_s: float
    events: deque[Event] = field(default_factory=deque)

    def clear(self) -> None:
        self.events.clear()

    def predict(self, filter_: Replayable, t_s: float) -> None:
        """``filter_.predict(t_s)``, kept."""
        if is_stale(filter_.t_s, t_s) or t_s <= filter_.t_s:  # a no-op (or the filter's error)
            filter_.predict(t_s)
            return
        self._run(filter_, Event(t_s, None, filter_.state()))

    def fuse(self, filter_: Replayable,
             measurements: Sequence[Measurement]) -> list[UpdateResult]:
        """Fuse ``measurements``: those older than the filter's time, or of an instant whose
        measurements it has fused already, at their own instant (:meth:`fuse_late`), the
        others as the filter does, an instant at a time; one result per measurement, in
        order."""
        results: dict[int, UpdateResult] = {}
        last = self.events[-1] if self.events else None
        fused_now = last is not None and last.measurements is not None and not is_stale(
            filter_.t_s, last.t_s)  # this instant's measurements have been fused
        late = [i for i, m in enumerate(measurements)
                if is_stale(filter_.t_s, m.t_s) or (fused_now and not is_stale(m.t_s, last.t_s))]
        for i in sorted(late, key=lambda i: measurements[i].t_s):
            results[i] = self.fuse_late(filter_, measurements[i])
        current = [i for i in range(len(measurements)) if i not in results]
        while current:
            t_s = measurements[current[0]].t_s
            instant = [i for i in current if measurements[i].t_s == t_s]
            current = [i for i in current if measurements[i].t_s != t_s]
            event = Event(t_s, [measurements[i] for i in instant], filter_.state())
            results.update(zip(instant, self._run(filter_, event), strict=True))
        return [results[i] for i in range(len(measurements))]

    def fuse_late(self, filter_: Replayable, measurement: Measurement) -> UpdateResult:
        """Fuse ``measurement`` at its own time and re-run the events after it; a
        measurement older than the history goes to the filter as it is (which rejects it
        as stale)."""
        t_s, events = measurement.t_s, self.events
        if not events or is_stale(events[0].before.t_s, t_s):
            return filter_.update_many([measurement])[0]
        # The first event after its instant, or its instant's measurements (a prediction
        # to the same instant, within the clocks' rounding, came before them).
        after = next((i for i, e in enumerate(events) if is_stale(e.t_s, t_s) or (
            e.measurements is not None and not is_stale(t_s, e.t_s))), None)
        if after is None:  # nothing after it (the filter was moved on outside the history)
            return filter_.update_many([measurement])[0]
        later = [events.pop() for _ in range(len(events) - after)][::-1]
        filter_.restore(later[0].before)
        if later[0].measurements is not None and not is_stale(later[0].t_s, t_s):
            first = later.pop(0)
            own = Event(t_s, [*first.measurements, measurement], first.before)
        else:
            own = Event(t_s, [measurement], later[0].before)
        result = self._run(filter_, own)[-1]
        for event in later:
            self._run(filter_, Event(event.t_s, event.measurements, filter_.state()))
        return result

    def _run(self, filter_: Replayable, event: Event) -> list[UpdateResult]:
        """Apply ``event`` (its ``before`` the filter's state now), keep it, drop what is
        older than the history."""
        results: list[UpdateResult] = []
        if event.measurements is None:
            filter_.predict(event.t_s)
        else:
            results = filter_.update_many(event.measurements)
        events = self.events
        events.append(event)
        horizon_s = filter_.t_s - self.history_s
        while len(events) > 1 and events[1].before.t_s <= horizon_s:
            events.popleft()
        return results


class FilterWithHistory:
    """A :class:`Replayable` filter that fuses late measurements at their own time
    (module docstring); every other call goes to the filter as it is. The runner calls it
    as it calls the filter (:mod:`estimation.protocol`); ``filter`` is the filter itself."""

    def __init__(self, filter_: Replayable, history_s: float) -> None:
        self.filter = filter_
        self.history = History(history_s)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.filter, name)  # what the history does not change: as it is

    @property
    def required_sensors(self) -> tuple[str, ...]:
        return self.filter.required_sensors

    @property
    def supported_sensors(self) -> tuple[str, ...]:
        return self.filter.supported_sensors

    def predict(self, t_s: float) -> None:
        self.history.predict(self.filter, t_s)

    def update(self, measurement: Measurement) -> UpdateResult:
        return self.history.fuse(self.filter, [measurement])[0]

    def update_many(self, measurements: Sequence[Measurement]) -> list[UpdateResult]:
        return self.history.fuse(self.filter, measurements)

    def command(self, t_s: float, steer_rad: float) -> None:
        """The filter's own timeline of commands: inputs, not state, so a re-run after a
        late measurement meets them again (:mod:`estimation.steering_commands`)."""
        self.filter.command(t_s, steer_rad)

    def accel_command(self, t_s: float, accel_mps2: float) -> None:
        """As :meth:`command` (:mod:`estimation.accel_commands`)."""
        self.filter.accel_command(t_s, accel_mps2)

    def estimate(self) -> Estimate:
        return self.filter.estimate()

    def estimate_at(self, t_s: float) -> Estimate:
        return self.filter.estimate_at(t_s)

    def counts(self) -> dict[str, dict[str, int]]:
        return self.filter.counts()

    def restart(self, initial: InitialState, *, t0_s: float = 0.0,
                rng: np.random.Generator | None = None) -> None:
        self.history.clear()
        self.filter.restart(initial, t0_s=t0_s, rng=rng)
