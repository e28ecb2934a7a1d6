"""Reference speed as part of the reference: constant, along the path, or over time.

A :class:`SpeedProfile` answers "how fast here and now" for arrays of arc lengths and
times (trackers ask for every stage of a horizon at once):

* :class:`ConstantSpeed`: one speed everywhere (the lane changes, the circle).
* :class:`SpatialSpeed`: a speed per arc length, linearly interpolated (periodic on a closed
  path). :func:`friction_limited` makes one for a circuit.
* :class:`TimedSpeed`: a speed per time, for manoeuvres that dwell, such as stop-and-go
  (:func:`stop_and_go`): a profile of arc length alone cannot restart a car that stopped.

The friction-limited profile is the forward-backward pass of quasi-steady-state lap-time
estimation (e.g. Kapania, Subosits and Gerdes, "A sequential two-step algorithm for fast
generation of vehicle racing trajectories", ASME J. Dynamic Systems, Measurement and Control
138(9), 2016; Heilmeier et al., "Minimum curvature trajectory planning and control for an
autonomous race car", Vehicle System Dynamics 58(10), 2020):

1. the cornering limit ``v <= sqrt(a_lat / |kappa|)`` (and the top speed);
2. forward: ``v_{i+1}^2 <= v_i^2 + 2 a_acc ds`` with the acceleration left by the friction
   ellipse, ``a_acc = a_long_max sqrt(1 - (v_i^2 kappa_i / a_lat)^2)``;
3. backward, the same with the braking limit, from the end towards the start.

On a closed path the passes go round twice, so the speed at the start line is the one the
previous lap arrives with.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from cosim.core.exceptions import ConfigError


class SpeedProfile:
    """The reference speed at arc lengths and times (equal-shaped or broadcastable arrays)."""

    top_speed_mps: float
    reads_arc_length: ClassVar[bool] = True
    """Whether the speed depends on the arc length (else its arc lengths serve only for
    the result's shape: a path need not wrap them first)."""

    def speed_mps(self, s_m: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def speed_at(self, s_m: float, t_s: float) -> float:
        """:meth:`speed_mps` at one arc length and one time, as a float (the metrics ask
        at every log instant)."""
        return float(self.speed_mps(np.asarray(s_m, dtype=float), np.asarray(t_s, dtype=float)))


@dataclass(frozen=True)
class ConstantSpeed(SpeedProfile):
    """One reference speed everywhere, always."""

    top_speed_mps: float
    reads_arc_length: ClassVar[bool] = False

    def speed_mps(self, s_m: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        return np.full(np.broadcast(np.asarray(s_m), np.asarray(t_s)).shape,
                       self.top_speed_mps)

    def speed_at(self, s_m: float, t_s: float) -> float:
        return float(self.top_speed_mps)


def _table(x: np.ndarray, v: np.ndarray, what: str) -> tuple[np.ndarray, np.ndarray]:
    x, v = np.asarray(x, dtype=float), np.asarray(v, dtype=float)
    if x.ndim != 1 or x.shape != v.shape or x.size < 2 or np.any(np.diff(x) <= 0.0):
        raise ConfigError(f"{what}: expected >= 2 increasing breakpoints with one speed each")
    if not np.all(np.isfinite(v)) or np.any(v < 0.0):
        raise ConfigError(f"{what}: expected finite speeds >= 0")
    return x, v


class _TabulatedSpeed(SpeedProfile):
    """Speeds at increasing breakpoints of one argument, linear between them."""

    speed_table_mps: np.ndarray

    def _breakpoints(self) -> np.ndarray:
        raise NotImplementedError

    def _argument(self, s_m: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def _period(self) -> float | None:
        """The period of the argument (a closed path's lap), None if it does not wrap."""
        return None

    @property
    def top_speed_mps(self) -> float:  # type: ignore[override]
        return float(np.max(self.speed_table_mps))

    def speed_mps(self, s_m: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        s, t = np.broadcast_arrays(np.asarray(s_m, dtype=float), np.asarray(t_s, dtype=float))
        return np.interp(self._argument(s, t), self._breakpoints(), self.speed_table_mps,
                         period=self._period())


@dataclass(frozen=True)
class SpatialSpeed(_TabulatedSpeed):
    """A speed per arc length (m/s at ``s_table_m``), linear between breakpoints."""

    s_table_m: np.ndarray
    speed_table_mps: np.ndarray
    period_m: float | None = None
    """The lap length of a closed path: arc lengths wrap (None: an open path, held at ends)."""

    def __post_init__(self) -> None:
        _table(self.s_table_m, self.speed_table_mps, "spatial speed profile")

    def _period(self) -> float | None:
        return self.period_m

    def _breakpoints(self) -> np.ndarray:
        return self.s_table_m

    def _argument(self, s_m: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        return s_m


@dataclass(frozen=True)
class TimedSpeed(_TabulatedSpeed):
    """A speed per time (m/s at ``t_table_s``), linear between breakpoints, held after."""

    t_table_s: np.ndarray
    reads_arc_length: ClassVar[bool] = False
    speed_table_mps: np.ndarray

    def __post_init__(self) -> None:
        _table(self.t_table_s, self.speed_table_mps, "timed speed profile")

    def _breakpoints(self) -> np.ndarray:
        return self.t_table_s

    def _argument(self, s_m: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        return t_s


def friction_limited(s_m: np.ndarray, curvature_1pm: np.ndarray, top_speed_mps: float,
                     lat_accel_max_mps2: float, accel_max_mps2: float,
                     decel_max_mps2: float, closed: bool) -> np.ndarray:
    """Speeds at ``s_m`` (increasing, equally or unequally spaced) limited by curvature and
    friction: the forward-backward pass of the module docstring. All limits positive."""
    s = np.asarray(s_m, dtype=float)
    kappa = np.abs(np.asarray(curvature_1pm, dtype=float))
    for name, value in (("lat_accel_max_mps2", lat_accel_max_mps2),
                        ("accel_max_mps2", accel_max_mps2),
                        ("decel_max_mps2", decel_max_mps2), ("top_speed_mps", top_speed_mps)):
        if not (np.isfinite(value) and value > 0.0):
            raise ConfigError(f"speed profile {name} = {value!r}: expected a positive number")
    limit = np.minimum(top_speed_mps,
                       np.sqrt(lat_accel_max_mps2 / np.maximum(kappa, 1e-9)))
    n = s.size
    ds = np.diff(s)
    if closed:  # the step from the last point back to the first, around the loop
        ds = np.append(ds, ds.mean())
    v = limit.copy()

    def available(speed: float, k: float, a_max: float) -> float:
        used = min(1.0, (speed * speed * k / lat_accel_max_mps2) ** 2)
        return a_max * np.sqrt(1.0 - used)

    laps = 2 if closed else 1
    for _ in range(laps):  # forward: what the car can accelerate to
        for i in range(n if closed else n - 1):
            j = (i + 1) % n
            reach = np.sqrt(v[i] ** 2 + 2.0 * available(v[i], kappa[i], accel_max_mps2) * ds[i])
            v[j] = min(v[j], reach)
    for _ in range(laps):  # backward: what the car can brake down from
        for i in range(n - 1 if closed else n - 2, -1, -1):
            j = (i + 1) % n
            reach = np.sqrt(v[j] ** 2 + 2.0 * available(v[j], kappa[j], decel_max_mps2) * ds[i])
            v[i] = min(v[i], reach)
    return v


def stop_and_go(cruise_speed_mps: float, cruise_s: float, stop_s: float,
                accel_mps2: float, decel_mps2: float, duration_s: float) -> TimedSpeed:
    """Cruise, brake to a full stop, stand, accelerate back, and again, until ``duration_s``.

    The cycle: ``cruise_s`` at ``cruise_speed_mps``, a ramp down at ``decel_mps2`` to zero,
    ``stop_s`` standing, a ramp up at ``accel_mps2``.
    """
    ramp_down_s = cruise_speed_mps / decel_mps2
    ramp_up_s = cruise_speed_mps / accel_mps2
    t, times, speeds = 0.0, [0.0], [cruise_speed_mps]
    while t < duration_s:
        for length_s, speed in ((cruise_s, cruise_speed_mps), (ramp_down_s, 0.0),
                                (stop_s, 0.0), (ramp_up_s, cruise_speed_mps)):
            t += length_s
            times.append(t)
            speeds.append(speed)
    return TimedSpeed(np.asarray(times), np.asarray(speeds))
