"""Estimators by name: what ``estimator.name`` selects and which sensors each one needs.

A name that is not built in is an estimator from outside cosim: an import path
``my_pkg.my_module:MyFilter`` or an entry point of the group ``cosim.estimators``
(:mod:`cosim.core.plugins`). Its class is built as the built-in ones are,
``cls(config, initial, belief, t0_s=..., rng=...)`` (its own settings in
``config.params``; ``rng`` draws its initial estimate), and must implement
:class:`estimation.protocol.Estimator`; the optional capabilities are the small protocols
beside it (:class:`~estimation.protocol.JointUpdater`,
:class:`~estimation.protocol.CountsUpdates`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from cosim.core.exceptions import ConfigError, PluginError
from cosim.core.initial_state import InitialState
from cosim.core.plugins import load_object, missing_members
from cosim.core.vehicle_params import VehicleParams
from estimation.config import ESTIMATOR_NAMES, PLUGIN_GROUP, EstimatorConfig, is_plugin_name
from estimation.ekf import Ekf
from estimation.fusion import KalmanFusion
from estimation.history import FilterWithHistory
from estimation.protocol import Estimator
from estimation.truth import TruthEstimator

if TYPE_CHECKING:  # imported when first used: filterpy imports scipy.stats (0.3 s)
    from estimation.ukf import Ukf

__all__ = [
    "ESTIMATOR_NAMES",
    "estimator_class",
    "make_estimator",
    "required_sensors",
    "supported_sensors",
]


def estimator_class(name: str) -> type[Ekf] | type[Ukf] | type[TruthEstimator]:
    """The class registered as ``name``; a :class:`ConfigError` listing the known ones."""
    if name == "ekf":
        return Ekf
    if name == "ukf":
        from estimation.ukf import Ukf  # noqa: PLC0415 (lazy: filterpy, scipy.stats)
        return Ukf
    if name == "truth":
        return TruthEstimator
    if is_plugin_name(name):
        return _plugin_class(name)
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
    around it with ``rng`` (``config.initial``, :mod:`estimation.initial`). With
    ``config.history_s`` a built-in filter fuses late measurements at their own time
    (:class:`estimation.history.FilterWithHistory`)."""
    estimator = estimator_class(config.name)(config, initial, belief, t0_s=t0_s, rng=rng)
    if config.history_s > 0.0 and isinstance(estimator, KalmanFusion):
        return FilterWithHistory(estimator, config.history_s)
    return estimator


def required_sensors(name: str) -> tuple[str, ...]:
    """Sensors the estimator ``name`` cannot work without (the run must provide them)."""
    return estimator_class(name).required_sensors


def supported_sensors(name: str) -> tuple[str, ...]:
    """Sensors the estimator ``name`` fuses (others are ignored, not rejected)."""
    return estimator_class(name).supported_sensors


def _plugin_class(name: str) -> Any:
    """An estimator class from outside cosim, checked for the methods the runner calls."""
    cls = load_object(name, PLUGIN_GROUP, "estimator.name")
    if not isinstance(cls, type):
        raise PluginError(f"estimator.name = {name!r}: is a {type(cls).__name__}: expected "
                          "an estimator class")
    missing = missing_members(cls, Estimator)
    missing += [a for a in ("required_sensors", "supported_sensors")
                if a not in missing and not isinstance(getattr(cls, a), tuple)]
    if missing:
        raise PluginError(f"estimator.name = {name!r}: class {cls.__name__} lacks "
                          f"{', '.join(missing)}: expected predict(t_s), estimate(), "
                          "update(measurement) and tuples required_sensors, supported_sensors")
    return cls
