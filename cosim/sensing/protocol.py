"""The interface of a sensor: a noisy view of the truth, sampled at its own period.

Noise, rate, bias and quantisation are properties of the observation, not of the physics
(as dm_control's observables have them); each sensor draws from its own generator, which
the runner derives from the run's seed and the sensor's name
(:mod:`cosim.core.sensor_names`).
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from cosim.core.records import Measurement, VehicleState


@runtime_checkable
class Sensor(Protocol):
    """A sensor: samples the truth every ``period_s`` with noise from ``rng``."""

    name: str
    """Its name (:mod:`cosim.core.sensor_names`): topic, generator, estimator model."""
    names: tuple[str, ...]
    """Its channels, in the order of :attr:`Measurement.values`."""
    period_s: float

    def sample(self, truth: VehicleState, rng: np.random.Generator) -> Measurement: ...


@runtime_checkable
class BiasedSensor(Protocol):
    """A sensor with biases of its own (a capability): their true values, for the log.

    The keys name the bias as the filters' states do (``gyro_bias_radps``, ...), so a plot
    can draw each bias estimate minus its truth; the values are what the sensor adds to
    its channels now. Reading them draws nothing and changes nothing.
    """

    def true_biases(self) -> dict[str, float]: ...
