"""The filter as the loop uses it: predicted for the controller, looked at, fed measurements.

Three uses, three contracts (:mod:`estimation.protocol`):

- :meth:`EstimatorPort.current`: the filter predicted to ``t_s`` and its estimate, for the
  controller; part of the loop (the filter's predictions follow the control and sensor
  instants, never the log's);
- :meth:`EstimatorPort.observed`: the estimate at ``t_s`` without changing the filter (for
  the log and the low-level layer), through ``estimate_at`` where the filter has it
  (:class:`ObservableEstimator`); otherwise its latest belief as it stands;
- :attr:`EstimatorPort.fuse`: the measurements of one instant, together where the filter
  can (:class:`JointUpdater`: one joint update, one gate), else one by one in order;
- :meth:`EstimatorPort.command`: the controller's command, from the time the software
  believes it acts, to a filter that takes it: the steering (:class:`TakesCommands`) and
  the acceleration (:class:`TakesAccelCommands`).

The capabilities are checked once, when the port is made: a protocol's ``isinstance``
costs some 4 us, and the log looks at every instant.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from cosim.core.records import Estimate, Measurement
from estimation.protocol import (
    CountsUpdates,
    Estimator,
    JointUpdater,
    ObservableEstimator,
    TakesAccelCommands,
    TakesCommands,
)
from estimation.update_result import UpdateResult


class EstimatorPort:
    """One estimator and the ways the loop calls it (module docstring)."""

    def __init__(self, estimator: Estimator) -> None:
        self.estimator = estimator
        self.fuse: Callable[[Sequence[Measurement]], list[UpdateResult]] = (
            estimator.update_many if isinstance(estimator, JointUpdater)
            else self._one_by_one)
        """Fuses the measurements of one instant: their update results, in order."""
        self._observable = estimator if isinstance(estimator, ObservableEstimator) else None
        self._commanded = estimator if isinstance(estimator, TakesCommands) else None
        self._accelerated = estimator if isinstance(estimator, TakesAccelCommands) else None
        self.localised = True
        """Whether the filter has been given a position fix, or needs none: the runner
        sets it False for a run with a receiver until its first fix is delivered (a fix
        ``sensors.gnss.latency_s`` late leaves the filter on its prior, a metre or so
        off, for that long), and the controller engages from then on."""

    def current(self, t_s: float) -> Estimate:
        """The filter predicted to ``t_s`` (it changes) and its estimate."""
        self.estimator.predict(t_s)
        return self.estimator.estimate()

    def observed(self, t_s: float) -> Estimate:
        """The estimate at ``t_s``, the filter unchanged."""
        if self._observable is not None:
            return self._observable.estimate_at(t_s)
        return self.estimator.estimate()

    def command(self, t_s: float, steer_rad: float, accel_mps2: float | None = None) -> None:
        """The command acting from ``t_s`` on, to a filter that takes it: the steering, and
        the acceleration where given."""
        if self._commanded is not None:
            self._commanded.command(t_s, steer_rad)
        if self._accelerated is not None and accel_mps2 is not None:
            self._accelerated.accel_command(t_s, accel_mps2)

    def counts(self) -> dict[str, dict[str, int]]:
        """Accepted, gated and ignored updates per sensor, where the filter counts them."""
        return self.estimator.counts() if isinstance(self.estimator, CountsUpdates) else {}

    def _one_by_one(self, measurements: Sequence[Measurement]) -> list[UpdateResult]:
        return [self.estimator.update(measurement) for measurement in measurements]
