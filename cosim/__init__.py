"""cosim: a MuJoCo co-simulation testbed for autonomous-car path tracking.

The Python API (:mod:`cosim.api`, worked example in ``docs/api.md``)::

    import cosim

    config = cosim.load_config("lane-change", seed=1)
    result = cosim.run(config, out="logs/run.mcap")
    outcome = cosim.sweep("examples/mass-friction.yaml", out="logs/sweep")

The names :data:`API_NAMES` are resolved on first use (PEP 562 module ``__getattr__``):
``import cosim`` imports no simulator, solver or plotting library and has no side effects.
``cosim.simulation`` (one run's machinery) and ``cosim.sweeps`` (sweeps) are sub-packages;
the functions ``cosim.run`` and ``cosim.sweep`` are the API's.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

API_NAMES: tuple[str, ...] = (
    "load_config", "run", "sweep", "RunResult", "ScenarioConfig", "SweepOutcome", "Workshop",
)
"""What ``cosim.<name>`` gives from :mod:`cosim.api`."""

TRACKER_NAMES: dict[str, str] = {
    "Command": "cosim.core.records", "Plan": "cosim.core.records",
    "Estimate": "cosim.core.records", "setting": "cosim.core.config_fields",
    "CosimError": "cosim.core.exceptions",
}
"""What a tracker of your own needs (``from cosim import Command``), and its module."""

if TYPE_CHECKING:
    from cosim.api import (
        RunResult,
        ScenarioConfig,
        SweepOutcome,
        Workshop,
        load_config,
        run,
        sweep,
    )
    from cosim.core.config_fields import setting
    from cosim.core.exceptions import CosimError
    from cosim.core.records import Command, Estimate, Plan

__all__ = [
    "Command", "CosimError", "Estimate", "Plan", "RunResult", "ScenarioConfig", "SweepOutcome",
    "Workshop", "__version__", "load_config", "run", "setting", "sweep",
]


def __getattr__(name: str) -> Any:
    """``cosim.run`` and the other API names, imported from :mod:`cosim.api` when asked."""
    if name in API_NAMES:
        from cosim import api

        return getattr(api, name)
    if name in TRACKER_NAMES:
        import importlib

        return getattr(importlib.import_module(TRACKER_NAMES[name]), name)
    raise AttributeError(f"module 'cosim' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), *API_NAMES, *TRACKER_NAMES})
