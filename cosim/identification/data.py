"""What the identification manoeuvres measure: steady turns and sampled responses.

Frames and units as everywhere in cosim: vehicle frame ISO 8855 (x forward, y left, z up),
steering positive to the left, SI units in every name.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cosim.core.exceptions import CosimError


class IdentificationError(CosimError):
    """A manoeuvre did not give usable data, or a fit failed."""


@dataclass(frozen=True)
class SteadyTurn:
    """Means over the steady part of a constant-steer, constant-speed turn."""

    vx_mps: float
    vy_mps: float
    yaw_rate_radps: float
    ay_mps2: float
    steer_rad: float
    """Measured road-wheel angle (mean of the two front wheels) [rad]."""

    def __post_init__(self) -> None:
        for name in ("vx_mps", "vy_mps", "yaw_rate_radps", "ay_mps2", "steer_rad"):
            if not math.isfinite(getattr(self, name)):
                raise IdentificationError(f"SteadyTurn.{name} = {getattr(self, name)!r}: "
                                          "expected a finite number")
        if self.vx_mps <= 0.0:
            raise IdentificationError(f"SteadyTurn.vx_mps = {self.vx_mps}: expected > 0")

    @property
    def speed_mps(self) -> float:
        """Speed of the centre of gravity, hypot(vx, vy) [m/s]."""
        return math.hypot(self.vx_mps, self.vy_mps)

    @property
    def radius_m(self) -> float:
        """Radius of the path of the centre of gravity, speed / yaw rate [m]."""
        return self.speed_mps / abs(self.yaw_rate_radps)

    @property
    def yaw_rate_gain_per_s(self) -> float:
        """Yaw rate per road-wheel angle, r / delta [1/s]."""
        return self.yaw_rate_radps / self.steer_rad

    def to_dict(self) -> dict[str, float]:
        return {"vx_mps": self.vx_mps, "vy_mps": self.vy_mps,
                "yaw_rate_radps": self.yaw_rate_radps, "ay_mps2": self.ay_mps2,
                "steer_rad": self.steer_rad}


def _check_series(owner: str, dt_s: float, series: dict[str, np.ndarray]) -> None:
    if not (math.isfinite(dt_s) and dt_s > 0.0):
        raise IdentificationError(f"{owner}.dt_s = {dt_s!r}: expected a positive period")
    lengths = {name: np.shape(values) for name, values in series.items()}
    first = next(iter(lengths.values()))
    if len(first) != 1 or first[0] < 2 or any(shape != first for shape in lengths.values()):
        raise IdentificationError(
            f"{owner}: expected 1-D series of one length >= 2, got "
            + ", ".join(f"{name} {shape}" for name, shape in lengths.items())
        )
    for name, values in series.items():
        if not np.all(np.isfinite(values)):
            raise IdentificationError(f"{owner}.{name}: expected finite samples")


@dataclass(frozen=True)
class LateralResponse:
    """A transient of the lateral dynamics, sampled every ``dt_s`` from its start.

    Sample ``k`` is at ``k dt_s``. ``steer_rad`` is the measured road-wheel angle, so the
    steering actuator's lag is not part of what a fit of the tyres sees.
    """

    dt_s: float
    steer_rad: np.ndarray
    vx_mps: np.ndarray
    vy_mps: np.ndarray
    yaw_rate_radps: np.ndarray

    def __post_init__(self) -> None:
        _check_series("LateralResponse", self.dt_s, {
            "steer_rad": self.steer_rad, "vx_mps": self.vx_mps, "vy_mps": self.vy_mps,
            "yaw_rate_radps": self.yaw_rate_radps})
        if np.min(self.vx_mps) <= 0.0:
            raise IdentificationError("LateralResponse.vx_mps: expected a forward speed > 0")

    @property
    def samples(self) -> int:
        return int(np.size(self.steer_rad))


@dataclass(frozen=True)
class StepResponse:
    """A commanded signal and the measured response of an actuator path, every ``dt_s``.

    ``command[k]`` is the command given at sample ``k`` (it acts over the following
    interval, after any transport delay); ``response[k]`` is measured at sample ``k``.
    """

    dt_s: float
    command: np.ndarray
    response: np.ndarray

    def __post_init__(self) -> None:
        _check_series("StepResponse", self.dt_s,
                      {"command": self.command, "response": self.response})

    @property
    def samples(self) -> int:
        return int(np.size(self.command))
