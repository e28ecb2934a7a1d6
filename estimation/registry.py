"""Estimators by name: what ``estimator.name`` selects and which sensors each one needs.

A name that is not built in is an estimator from outside cosim: an import path
``my_pkg.my_module:MyFilter`` or an entry point of the group ``cosim.estimators``
(:mod:`cosim.core.plugins`). Its class is built as the built-in ones are,
``cls(config, initial, belief, t0_s=..., rng=...)`` (its own settings in
``config.params``; ``rng`` draws its initial estimate), and must
have ``predict(t_s)``, ``estimate() -> Estimate`` and ``update(measurement)`` returning an
:class:`estimation.update_result.UpdateResult`, plus the class attributes
``required_sensors`` and ``supported_sensors``. It may also have
``update_many(measurements) -> list[UpdateResult]`` for measurements of one instant (the
built-in filters fuse them in one update); without it the runner calls ``update`` for each.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, TypeAlias

import numpy as np

from cosim.core.exceptions import ConfigError, PluginError
from cosim.core.initial_state import InitialState
from cosim.core.plugins import load_object
from cosim.core.vehicle_params import VehicleParams
from estimation.config import ESTIMATOR_NAMES, PLUGIN_GROUP, EstimatorConfig, is_plugin_name
from estimation.ekf import Ekf
from estimation.truth import TruthEstimator

if TYPE_CHECKING:  # imported when first used: filterpy imports scipy.stats (0.3 s)
    from estimation.ukf import Ukf

    Estimator: TypeAlias = Ekf | Ukf | TruthEstimator
    """What :func:`make_estimator` returns (plug-ins follow the same protocol)."""

__all__ = [
    "ESTIMATOR_NAMES",
    "estimator_class",
    "make_estimator",
    "required_sensors",
    "supported_sensors",
]


ESTIMATOR_METHODS = ("predict", "estimate", "update")
"""What the runner calls on an estimator."""


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
    around it with ``rng`` (``config.initial``, :mod:`estimation.initial`)."""
    return estimator_class(config.name)(config, initial, belief, t0_s=t0_s, rng=rng)


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
    missing = [m for m in ESTIMATOR_METHODS if not callable(getattr(cls, m, None))]
    missing += [a for a in ("required_sensors", "supported_sensors")
                if not isinstance(getattr(cls, a, None), tuple)]
    if missing:
        raise PluginError(f"estimator.name = {name!r}: class {cls.__name__} lacks "
                          f"{', '.join(missing)}: expected predict(t_s), estimate(), "
                          "update(measurement) and tuples required_sensors, supported_sensors")
    return cls
