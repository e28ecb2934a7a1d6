"""The plant, sensor and estimator interfaces of a run (the tracker's: tracker/protocol.py).

A tracker never sees the plant; an estimator never sees the truth (the debugging estimator
``truth`` receives it as a noise-free measurement from the ``truth`` sensor).
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from cosim.core.records import ActuatorCommand, Estimate, Measurement, VehicleState


class Plant(Protocol):
    """The simulated car."""

    physics_dt_s: float

    def reset(self) -> None: ...

    def apply(self, actuator: ActuatorCommand) -> None:
        """Set the actuators' targets (wheel torques, road-wheel angle); they act from the
        next :meth:`advance` on. The tracker's :class:`Command` reaches the plant through
        the delay line and the low-level layer (:mod:`cosim.plant.low_level`)."""

    def advance(self) -> None:
        """Advance the physics by one step of ``physics_dt_s``."""

    def state(self) -> VehicleState: ...


class Sensor(Protocol):
    """A sensor: samples the truth every ``period_s`` with noise from its own generator."""

    name: str
    period_s: float

    def sample(self, truth: VehicleState, rng: np.random.Generator) -> Measurement: ...


class UpdateResult(Protocol):
    accepted: bool
    nis: float
    dim: int


class Estimator(Protocol):
    """A state estimator fed asynchronously by the sensors."""

    def predict(self, t_s: float) -> None:
        """Propagate the belief to time ``t_s`` (no-op if already there)."""

    def update(self, measurement: Measurement) -> UpdateResult:
        """Fuse one measurement (predicting to its time first)."""

    def estimate(self) -> Estimate: ...


@runtime_checkable
class ObservableEstimator(Protocol):
    """An estimator that can be looked at between its own steps without being changed."""

    def estimate_at(self, t_s: float) -> Estimate:
        """The belief predicted to ``t_s``; the estimator itself stays as it was."""
