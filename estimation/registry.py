"""Estimators by name: what ``estimator.name`` selects and which sensors each one needs."""

from __future__ import annotations

import numpy as np

from cosim.exceptions import ConfigError
from cosim.initial_state import InitialState
from cosim.vehicle_params import VehicleParams
from estimation.config import ESTIMATOR_NAMES, EstimatorConfig
from estimation.ekf import Ekf
from estimation.truth import TruthEstimator
from estimation.ukf import Ukf

__all__ = [
    "ESTIMATOR_NAMES",
    "Estimator",
    "estimator_class",
    "make_estimator",
    "required_sensors",
    "supported_sensors",
]


Estimator = Ekf | Ukf | TruthEstimator


def estimator_class(name: str) -> type[Ekf] | type[Ukf] | type[TruthEstimator]:
    """The class registered as ``name``; a :class:`ConfigError` listing the known ones."""
    if name == "ekf":
        return Ekf
    if name == "ukf":
        return Ukf
    if name == "truth":
        return TruthEstimator
    raise ConfigError(f"estimator.name = {name!r}: expected one of {', '.join(ESTIMATOR_NAMES)}")


def make_estimator(
    config: EstimatorConfig,
    initial: InitialState,
    belief: VehicleParams,
    *,
    t0_s: float = 0.0,
    rng: np.random.Generator | None = None,
) -> Estimator:
    """Build the estimator ``config.name`` with its initial belief at ``t0_s``.

    ``initial`` is the car's true initial state; the filters draw their initial estimate
    around it with ``rng`` (``config.initial``, :mod:`estimation.initial`)."""
    return estimator_class(config.name)(config, initial, belief, t0_s=t0_s, rng=rng)


def required_sensors(name: str) -> tuple[str, ...]:
    """Sensors the estimator ``name`` cannot work without (the run must provide them)."""
    return estimator_class(name).required_sensors


def supported_sensors(name: str) -> tuple[str, ...]:
    """Sensors the estimator ``name`` fuses (others are ignored, not rejected)."""
    return estimator_class(name).supported_sensors
