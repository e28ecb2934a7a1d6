"""Trackers by name: ``tracker.name`` in a scenario picks the constructor.

A tracker is anything with ``step(t_s, estimate, reference) -> (Command, Plan)`` and
``reset()`` (the :class:`cosim.core.protocols.Tracker` protocol). A name that is not built in is a
tracker from outside cosim (an import path or an installed plug-in: :mod:`tracker.plugin`),
or a co-simulation FMU, ``fmu:PATH.fmu`` (:mod:`tracker.fmu`).
"""

from __future__ import annotations

from collections.abc import Callable
from types import MappingProxyType

from cosim.core.exceptions import ConfigError
from tracker.acc.law import AccTracker
from tracker.baselines.lqr import make_lqr
from tracker.baselines.pid import make_pid
from tracker.baselines.pure_pursuit import make_pure_pursuit
from tracker.baselines.stanley import make_stanley
from tracker.config import TrackerConfig, is_plugin_name
from tracker.fmu import make_fmu_tracker
from tracker.fmu.config import is_fmu_name
from tracker.maneuver import ManeuverConfig
from tracker.mpc.dynamic_mpc import DynamicMpc
from tracker.mpc.dynamic_nmpc import DynamicNmpc
from tracker.mpc.kinematic_nmpc import KinematicNmpc
from tracker.mpc.ltv_mpc import LtvMpc
from tracker.open_loop import OpenLoopTracker
from tracker.plugin import make_plugin_tracker
from tracker.protocol import Tracker

_CONSTRUCTORS: MappingProxyType[
    str, Callable[[TrackerConfig, ManeuverConfig], Tracker]
] = MappingProxyType(
    {
        "kinematic-nmpc": lambda config, maneuver: KinematicNmpc(config),
        "dynamic-nmpc": lambda config, maneuver: DynamicNmpc(config),
        "dynamic-mpc": lambda config, maneuver: DynamicMpc(config),
        "ltv-mpc": lambda config, maneuver: LtvMpc(config),
        "open-loop": OpenLoopTracker,
        "pid": lambda config, maneuver: make_pid(config),
        "stanley": lambda config, maneuver: make_stanley(config),
        "pure-pursuit": lambda config, maneuver: make_pure_pursuit(config),
        "lqr": lambda config, maneuver: make_lqr(config),
    }
)

TRACKER_NAMES: tuple[str, ...] = tuple(_CONSTRUCTORS)
"""Every tracker name :func:`make_tracker` knows (the choices of ``tracker.name``)."""


def make_tracker(config: TrackerConfig, maneuver: ManeuverConfig | None = None,
                 control_period_s: float | None = None) -> Tracker:
    """Build the tracker ``config.name``; ``maneuver`` drives the ``open-loop`` tracker;
    ``control_period_s`` is how often the runner will call ``step`` (``sim.control_period_s``:
    an FMU's communication step; ``tracker.dt_s`` when not given).

    With ``tracker.acc.enabled`` it steers and the ACC (:class:`tracker.acc.law.AccTracker`,
    updated every ``tracker.dt_s``) sets the acceleration."""
    if is_fmu_name(config.name):
        tracker: Tracker = make_fmu_tracker(
            config, control_period_s if control_period_s is not None else config.dt_s)
    else:
        tracker = _make_path_tracker(config, maneuver)
    if config.acc.enabled:
        return AccTracker(tracker, config.acc, config.dt_s)
    return tracker


def _make_path_tracker(config: TrackerConfig, maneuver: ManeuverConfig | None) -> Tracker:
    constructor = _CONSTRUCTORS.get(config.name)
    if constructor is None and is_plugin_name(config.name):
        return make_plugin_tracker(config)
    if constructor is None:
        raise ConfigError(
            f"tracker.name = {config.name!r}: expected one of {', '.join(TRACKER_NAMES)}"
        )
    return constructor(config, maneuver if maneuver is not None else ManeuverConfig())
