"""Trackers by name: ``tracker.name`` in a scenario picks the constructor.

A tracker implements :class:`tracker.protocol.Tracker` (``step(t_s, estimate, reference)
-> (Command, Plan)``), and :class:`tracker.protocol.Resettable` when it has memory to
forget. A name that is not built in is a tracker from outside cosim (an import path or an
installed plug-in: :mod:`tracker.plugins.loading`), or a co-simulation FMU, ``fmu:PATH.fmu``
(:mod:`tracker.fmu`).
"""

from __future__ import annotations

from collections.abc import Callable
from types import MappingProxyType

from cosim.core.exceptions import ConfigError
from tracker.baselines.lqr import make_lqr
from tracker.baselines.pid import make_pid
from tracker.baselines.pure_pursuit import make_pure_pursuit
from tracker.baselines.stanley import make_stanley
from tracker.config import TrackerConfig, is_plugin_name
from tracker.cruise.law import AccTracker
from tracker.fmu import make_fmu_tracker
from tracker.fmu.config import is_fmu_name
from tracker.manoeuvre import ManoeuvreConfig
from tracker.mpc.dynamic_mpc import DynamicMpc
from tracker.mpc.dynamic_nmpc import DynamicNmpc
from tracker.mpc.kinematic_nmpc import KinematicNmpc
from tracker.mpc.ltv_mpc import LtvMpc
from tracker.open_loop import OpenLoopTracker
from tracker.plugins.loading import make_plugin_tracker
from tracker.protocol import Tracker

_CONSTRUCTORS: MappingProxyType[
    str, Callable[[TrackerConfig, ManoeuvreConfig], Tracker]
] = MappingProxyType(
    {
        "kinematic-nmpc": lambda config, manoeuvre: KinematicNmpc(config),
        "dynamic-nmpc": lambda config, manoeuvre: DynamicNmpc(config),
        "dynamic-mpc": lambda config, manoeuvre: DynamicMpc(config),
        "ltv-mpc": lambda config, manoeuvre: LtvMpc(config),
        "open-loop": OpenLoopTracker,
        "pid": lambda config, manoeuvre: make_pid(config),
        "stanley": lambda config, manoeuvre: make_stanley(config),
        "pure-pursuit": lambda config, manoeuvre: make_pure_pursuit(config),
        "lqr": lambda config, manoeuvre: make_lqr(config),
    }
)

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
    return constructor(config, manoeuvre if manoeuvre is not None else ManoeuvreConfig())
