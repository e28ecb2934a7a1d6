"""Sensor faults as data: the ``faults:`` list of a scenario.

Each fault acts on one sensor's measurements inside a time window ``[start_s, end_s)``;
with ``end_s`` left at its default (equal to ``start_s``) it hits the first sample at or
after ``start_s`` only. Faults act on the measurement, after the sensor's own noise, so the
estimator sees them exactly as a real receiver would deliver them:

- ``dropout``: no measurement at all (a GNSS outage in a tunnel);
- ``outlier``: the values jump by ``offset`` (for GNSS position and velocity, ``offset``
  east and ``offset_north`` north, in m or m/s; for other sensors, ``offset`` on every
  chosen channel);
- ``stuck``: the values freeze at the last good sample;
- ``nan``: the values are NaN (a driver or bus fault).

``channel`` restricts ``outlier``, ``stuck`` and ``nan`` to one named channel.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from cosim.core.config_fields import setting
from cosim.core.exceptions import ConfigError
from cosim.core.records import Measurement
from cosim.core.sensor_names import FUSED_SENSORS, GNSS, GNSS_VELOCITY

FAULT_KINDS = ("dropout", "outlier", "stuck", "nan")
FAULT_SENSORS = FUSED_SENSORS
"""Sensors a fault can act on: every one the estimator fuses."""


@dataclass(frozen=True)
class FaultConfig:
    """One fault of one sensor over a time window."""

    kind: str = setting("dropout", choices=FAULT_KINDS)
    sensor: str = setting(GNSS, choices=FAULT_SENSORS)
    start_s: float = setting(0.0, low=0.0, high=1e6)
    end_s: float = setting(-1.0, low=-1.0, high=1e6, doc="-1: only the first sample")
    offset: float = setting(0.0, low=-1e6, high=1e6, doc="outlier jump (GNSS: east, m or m/s)")
    offset_north: float = setting(0.0, low=-1e6, high=1e6, doc="GNSS outlier, north (m or m/s)")
    channel: str = setting("", doc="one channel name, or empty for all")

    def __post_init__(self) -> None:
        if self.end_s != -1.0 and self.end_s < self.start_s:
            raise ConfigError(
                f"end_s = {self.end_s}: expected -1 (first sample only) or at least "
                f"start_s = {self.start_s}"
            )


class FaultInjector:
    """Applies the faults of one sensor to its measurements, in time order."""

    def __init__(self, faults: tuple[FaultConfig, ...], sensor: str,
                 channels: tuple[str, ...]) -> None:
        self._faults = [f for f in faults if f.sensor == sensor]
        for fault in self._faults:
            if fault.channel and fault.channel not in channels:
                raise ConfigError(
                    f"faults: channel = {fault.channel!r} of sensor {sensor!r}: expected one "
                    f"of {', '.join(channels)}"
                )
        self._channels = channels
        self._fired: set[int] = set()
        self._last_good: np.ndarray | None = None
        self.injected = 0
        """Measurements changed or dropped so far."""

    def _active(self, index: int, fault: FaultConfig, t_s: float) -> bool:
        if fault.end_s == -1.0:
            if index in self._fired or t_s < fault.start_s:
                return False
            self._fired.add(index)
            return True
        return fault.start_s <= t_s < fault.end_s

    def apply(self, measurement: Measurement) -> Measurement | None:
        """The measurement as delivered, or ``None`` when a dropout swallows it."""
        if not self._faults:  # (a sensor without faults: every sample as it is)
            return measurement
        values = measurement.values.copy()
        changed = False
        for index, fault in enumerate(self._faults):
            if not self._active(index, fault, measurement.t_s):
                continue
            mask = np.ones(len(self._channels), dtype=bool)
            if fault.channel:
                mask = np.array([name == fault.channel for name in self._channels])
            if fault.kind == "dropout":
                self.injected += 1
                return None
            if fault.kind == "outlier":
                if measurement.sensor in (GNSS, GNSS_VELOCITY) and not fault.channel:
                    values = values + np.array([fault.offset, fault.offset_north])
                else:
                    values = np.where(mask, values + fault.offset, values)
            elif fault.kind == "stuck" and self._last_good is not None:
                values = np.where(mask, self._last_good, values)
            elif fault.kind == "nan":
                values = np.where(mask, np.nan, values)
            changed = True
        if not changed:
            self._last_good = values
            return measurement
        self.injected += 1
        return dataclasses.replace(measurement, values=values)
