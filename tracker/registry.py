"""Trackers by name: ``tracker.name`` in a scenario picks the constructor.

A tracker implements :class:`tracker.protocol.Tracker` (``step(t_s, estimate, reference)
-> (Command, Plan)``), and :class:`tracker.protocol.Resettable` when it has memory to
forget. A name that is not built in is a tracker from outside cosim (an import path or an
installed plug-in: :mod:`tracker.plugins.loading`), or a co-simulation FMU, ``fmu:PATH.fmu``
(:mod:`tracker.fmu`).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from types import MappingProxyType

from cosim.core.exceptions import ConfigError
from tracker.config import TrackerConfig, is_plugin_name
from tracker.fmu import make_fmu_tracker
from tracker.fmu.config import is_fmu_name
from tracker.manoeuvre import ManoeuvreConfig
from tracker.plugins.loading import make_plugin_tracker
from tracker.protocol import Tracker


@dataclass(frozen=True)
class _Constructor:
    """A built-in tracker's constructor, ``module.name``, imported when a run asks for it."""

    module: str
    name: str
    takes_manoeuvre: bool = False
    """Called with the manoeuvre it replays after the configuration (``open-loop``)."""

    def build(self, config: TrackerConfig, manoeuvre: ManoeuvreConfig) -> Tracker:
        constructor = getattr(importlib.import_module(self.module), self.name)
        return constructor(config, manoeuvre) if self.takes_manoeuvre else constructor(config)


_CONSTRUCTORS: MappingProxyType[str, _Constructor] = MappingProxyType({
    "kinematic-nmpc": _Constructor("tracker.mpc.kinematic_nmpc", "KinematicNmpc"),
    "dynamic-nmpc": _Constructor("tracker.mpc.dynamic_nmpc", "DynamicNmpc"),
    "dynamic-mpc": _Constructor("tracker.mpc.dynamic_mpc", "DynamicMpc"),
    "ltv-mpc": _Constructor("tracker.mpc.ltv_mpc", "LtvMpc"),
    "open-loop": _Constructor("tracker.open_loop", "OpenLoopTracker", takes_manoeuvre=True),
    "pid": _Constructor("tracker.baselines.pid", "make_pid"),
    "stanley": _Constructor("tracker.baselines.stanley", "make_stanley"),
    "pure-pursuit": _Constructor("tracker.baselines.pure_pursuit", "make_pure_pursuit"),
    "lqr": _Constructor("tracker.baselines.lqr", "make_lqr"),
})
"""Each built-in tracker's constructor, imported when a run asks for it: a process imports
the code of the trackers it runs, not of all nine (with the ACC's, some 20 ms of every
``cosim run``'s start)."""

TRACKER_NAMES: tuple[str, ...] = tuple(_CONSTRUCTORS)
"""Every tracker name :func:`make_tracker` knows (the choices of ``tracker.name``)."""


def make_tracker(config: TrackerConfig, manoeuvre: ManoeuvreConfig | None = None,
                 control_period_s: float | None = None) -> Tracker:
    """Build the tracker ``config.name``; ``manoeuvre`` drives the ``open-loop`` tracker;
    ``control_period_s`` is how often the runner will call ``step`` (``sim.control_period_s``:
    an FMU's communication step; ``tracker.dt_s`` when not given).

    With ``tracker.acc.enabled`` it steers and the ACC (:class:`tracker.cruise.law.AccTracker`,
    updated every ``tracker.dt_s``) sets the acceleration."""
    if is_fmu_name(config.name):
        tracker: Tracker = make_fmu_tracker(
            config, control_period_s if control_period_s is not None else config.dt_s)
    else:
        tracker = _make_path_tracker(config, manoeuvre)
    if config.acc.enabled:
        from tracker.cruise.law import AccTracker

        return AccTracker(tracker, config.acc, config.dt_s)
    return tracker


def _make_path_tracker(config: TrackerConfig, manoeuvre: ManoeuvreConfig | None) -> Tracker:
    constructor = _CONSTRUCTORS.get(config.name)
    if constructor is None and is_plugin_name(config.name):
        return make_plugin_tracker(config)
    if constructor is None:
        raise ConfigError(
            f"tracker.name = {config.name!r}: expected one of {', '.join(TRACKER_NAMES)}"
        )
    return constructor.build(config, manoeuvre if manoeuvre is not None else ManoeuvreConfig())
