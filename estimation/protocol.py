"""The interface every state estimator implements, and its optional capabilities.

The runner builds an estimator as ``cls(config, initial, belief, t0_s=..., rng=...)``
(:func:`estimation.registry.make_estimator`; ``rng`` draws its initial estimate, never the
truth) and then calls only what :class:`Estimator` declares; a capability beyond it is a
small protocol of its own that the runner tests with ``isinstance``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol, runtime_checkable

import numpy as np

from cosim.core.initial_state import InitialState
from cosim.core.records import Estimate, Measurement
from estimation.update_result import UpdateResult


@runtime_checkable
class Estimator(Protocol):
    """A state estimator fed asynchronously by the sensors.

    ``required_sensors`` are the sensors it cannot work without (the run must provide
    them; the ``truth`` estimator asks for the ``truth`` sensor, which the runner then
    adds); ``supported_sensors`` the ones it fuses (a measurement of any other is ignored,
    ``reason == "ignored"``, not rejected). Both are class attributes, so the registry
    reads them before building one.
    """

    required_sensors: tuple[str, ...]
    supported_sensors: tuple[str, ...]

    def predict(self, t_s: float) -> None:
        """Propagate the belief to time ``t_s`` (no-op if already there)."""

    def update(self, measurement: Measurement) -> UpdateResult:
        """Fuse one measurement (predicting to its time first); a refused one says why in
        :attr:`UpdateResult.reason`, it never raises."""

    def estimate(self) -> Estimate:
        """The current mean and covariance, by state name."""


@runtime_checkable
class JointUpdater(Protocol):
    """An estimator that fuses the measurements of one instant in one update (the built-in
    filters); without it the runner calls :meth:`Estimator.update` for each."""

    def update_many(self, measurements: Sequence[Measurement]) -> list[UpdateResult]:
        """One result per measurement, in order."""


@runtime_checkable
class CountsUpdates(Protocol):
    """An estimator that counts, per sensor, what it did with its measurements: the run's
    ``rejected_*``, ``channels_gated`` and ``estimator_surprises`` metrics."""

    def counts(self) -> dict[str, dict[str, int]]:
        """Per sensor, counter name to count (``rejected_gate``, ``channels_gated``,
        ``surprises`` ...)."""


@runtime_checkable
class ObservableEstimator(Protocol):
    """An estimator that can be looked at between its own steps without being changed (the
    runner's observers, e.g. the live view, look through it; without it they see
    :meth:`Estimator.estimate`)."""

    def estimate_at(self, t_s: float) -> Estimate:
        """The belief predicted to ``t_s``; the estimator itself stays as it was."""


@runtime_checkable
class TakesCommands(Protocol):
    """An estimator told the controller's steering commands (the built-in filters drive
    their steering states with them, :mod:`estimation.steering_model`)."""

    def command(self, t_s: float, steer_rad: float) -> None:
        """The command ``steer_rad`` acts on the steering actuator from ``t_s`` on, as the
        software believes (the control instant plus ``tracker.latency_s``)."""


@runtime_checkable
class TakesAccelCommands(Protocol):
    """An estimator told the controller's acceleration commands (the built-in filters move
    their acceleration with them, :mod:`estimation.accel_commands`)."""

    def accel_command(self, t_s: float, accel_mps2: float) -> None:
        """The command ``accel_mps2`` acts on the drive from ``t_s`` on, as the software
        believes (the control instant plus ``tracker.latency_s``)."""


@runtime_checkable
class Restartable(Protocol):
    """An estimator that can start a new run from a new initial belief, keeping what it
    built from its configuration and belief (the built-in filters keep their compiled
    models): the same run, bit for bit, as a newly built one with these arguments."""

    def restart(self, initial: InitialState, *, t0_s: float = 0.0,
                rng: np.random.Generator | None = None) -> None:
        """Forget every measurement and prediction; draw the initial belief around
        ``initial`` with ``rng`` at ``t0_s``, as the constructor does."""
