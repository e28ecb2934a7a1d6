"""Settings of an FMU tracker: the ``tracker.fmu:`` section (``--tracker fmu:PATH.fmu``)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from cosim.core.config_fields import mapping, setting

FMU_PREFIX = "fmu:"
"""``tracker.name`` of an FMU tracker: this prefix, then the FMU's path (relative to the
working directory, like ``path.file``)."""

MAX_PREVIEW_POINTS = 1000
"""The highest preview index an FMU may declare (``preview_x_m[1000]``)."""


def is_fmu_name(name: str) -> bool:
    """Whether ``tracker.name`` names an FMU (``fmu:PATH.fmu``)."""
    return name.startswith(FMU_PREFIX)


def fmu_path(name: str) -> str:
    """The FMU's path in ``tracker.name = fmu:PATH``."""
    return name.removeprefix(FMU_PREFIX)


@dataclass(frozen=True)
class FmuConfig:
    """A co-simulation FMU as the tracker (:mod:`tracker.fmu`): how cosim feeds it."""

    preview_spacing_m: float = setting(
        2.0, low=0.05, high=100.0,
        doc="arc length between the reference's preview points preview_x_m[i], "
        "preview_y_m[i] (point i lies i * spacing ahead of the estimate's projection)")
    parameters: dict[str, Any] = mapping(
        doc="FMU parameters set before its initialisation, by variable name, e.g. "
        "--set tracker.fmu.parameters.gain=2 (each must be a parameter of the FMU; numbers "
        "for Real/Float64, integers for Integer/Int32, true/false for Boolean)")
