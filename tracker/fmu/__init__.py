"""A co-simulation FMU (FMI 2 or FMI 3) as the path tracker: ``--tracker fmu:PATH.fmu``.

- :mod:`tracker.fmu.config`: the ``tracker.fmu:`` settings and the ``fmu:`` name;
- :mod:`tracker.fmu.signals`: the one table of what cosim serves and reads, by name;
- :mod:`tracker.fmu.units`: a declared unit against the unit a name implies;
- :mod:`tracker.fmu.description`: the FMU read and checked before any run (fmpy);
- :mod:`tracker.fmu.slave`: the FMU extracted, instantiated and stepped (fmpy);
- :mod:`tracker.fmu.tracker`: the :class:`tracker.protocol.Tracker` around it.

fmpy is an optional dependency (``pip install 'cosim[fmu]'``): only the last three modules
import it, and only when an FMU tracker is asked for; without it, one line says how to
install it.
"""

from __future__ import annotations

import importlib.util
from typing import TYPE_CHECKING

from cosim.core.exceptions import PluginError

if TYPE_CHECKING:  # tracker.config imports this package's config
    from tracker.config import TrackerConfig
    from tracker.fmu.tracker import FmuTracker


def _require_fmpy(name: str) -> None:
    if importlib.util.find_spec("fmpy") is None:
        raise PluginError(f"tracker.name = {name!r}: an FMU tracker needs fmpy: "
                          "pip install 'cosim[fmu]' (or pip install fmpy)")


def check_fmu(config: TrackerConfig, control_period_s: float,
              state_names: tuple[str, ...] | None = None) -> None:
    """Read and check the FMU ``config.name`` before any run (:func:`describe
    <tracker.fmu.description.describe>`); a bad FMU is a one-line :class:`PluginError`."""
    _require_fmpy(config.name)
    from tracker.fmu.description import describe  # fmpy: imported only for an FMU

    describe(config.name, config.fmu, control_period_s, state_names)


def make_fmu_tracker(config: TrackerConfig, control_period_s: float) -> FmuTracker:
    """The FMU ``config.name`` loaded, initialised and ready to step every
    ``control_period_s``."""
    _require_fmpy(config.name)
    from tracker.fmu.tracker import FmuTracker  # fmpy: imported only for an FMU

    return FmuTracker(config, control_period_s)
