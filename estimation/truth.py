"""The debugging estimator: hands the true state through as the estimate.

It reads the noise-free ``truth`` sensor (every scalar field of
:class:`cosim.core.records.VehicleState`) and returns it with a zero covariance (it is certain;
consistency figures such as NEES are undefined for it), so a tracker can be tested without
estimation error. Between two truth samples the motion is extrapolated with the measured
accelerations and yaw rate. Every other sensor is ignored (not a rejection).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from cosim.core.initial_state import InitialState
from cosim.core.records import Estimate, Measurement
from cosim.core.sensor_names import TRUTH
from cosim.core.vehicle_params import VehicleParams
from estimation.config import EstimatorConfig
from estimation.state import VEHICLE_STATE_NAMES, wrap_angle
from estimation.timing import forward_interval_s, is_stale
from estimation.update_result import (
    ACCEPTED,
    IGNORED,
    NON_FINITE,
    STALE,
    SensorCounts,
    UpdateResult,
)

TRUTH_STATE_NAMES: tuple[str, ...] = VEHICLE_STATE_NAMES + tuple(
    name
    for name in ("ay_mps2", "steer_rad", "z_m", "roll_rad", "pitch_rad")
    if name not in VEHICLE_STATE_NAMES
)
"""The filters' vehicle states followed by the rest of the truth's scalar fields."""

_ANGLE_NAMES: tuple[str, ...] = ("yaw_rad", "roll_rad", "pitch_rad", "steer_rad")


class TruthEstimator:
    """Estimator that returns the ``truth`` sensor's latest sample.

    Constructed like every estimator; ``config`` and ``belief`` are unused. Until the first
    truth sample it reports ``initial`` (at rest except for the forward speed).
    """

    required_sensors: tuple[str, ...] = (TRUTH,)
    supported_sensors: tuple[str, ...] = (TRUTH,)
    state_names: tuple[str, ...] = TRUTH_STATE_NAMES

    def __init__(
        self,
        config: EstimatorConfig,
        initial: InitialState,
        belief: VehicleParams,
        *,
        t0_s: float = 0.0,
        rng: np.random.Generator | None = None,
    ) -> None:
        if not math.isfinite(t0_s):
            raise ValueError(f"t0_s = {t0_s!r}: expected a finite time")
        del config, belief, rng  # the truth needs no tuning, no model and no draw
        values = dict.fromkeys(TRUTH_STATE_NAMES, 0.0)
        values.update(
            x_m=initial.x_m,
            y_m=initial.y_m,
            yaw_rad=wrap_angle(initial.yaw_rad),
            vx_mps=initial.speed_mps,
        )
        self._mean = np.array([float(values[name]) for name in TRUTH_STATE_NAMES])
        self._t_s = float(t0_s)
        self._counts: dict[str, SensorCounts] = {}

    @property
    def t_s(self) -> float:
        return self._t_s

    def predict(self, t_s: float) -> None:
        """Extrapolate the last truth to ``t_s`` (constant accelerations and yaw rate)."""
        dt_s = forward_interval_s(self._t_s, float(t_s), "estimator")
        if dt_s == 0.0:
            return
        s = dict(zip(TRUTH_STATE_NAMES, self._mean, strict=True))
        r = s["yaw_rate_radps"]
        # Body-frame velocity change from the kinematic accelerations (a = dv/dt + r x v),
        # then the pose with the mid-interval velocity and heading (second order).
        vx_dot = s["ax_mps2"] + r * s["vy_mps"]
        vy_dot = s["ay_mps2"] - r * s["vx_mps"]
        vx_mid = s["vx_mps"] + 0.5 * vx_dot * dt_s
        vy_mid = s["vy_mps"] + 0.5 * vy_dot * dt_s
        yaw_mid = s["yaw_rad"] + 0.5 * r * dt_s
        s["x_m"] += (vx_mid * math.cos(yaw_mid) - vy_mid * math.sin(yaw_mid)) * dt_s
        s["y_m"] += (vx_mid * math.sin(yaw_mid) + vy_mid * math.cos(yaw_mid)) * dt_s
        s["yaw_rad"] = wrap_angle(s["yaw_rad"] + r * dt_s)
        s["vx_mps"] += vx_dot * dt_s
        s["vy_mps"] += vy_dot * dt_s
        self._mean = np.array([float(s[name]) for name in TRUTH_STATE_NAMES])
        self._t_s = t_s

    def update(self, measurement: Measurement) -> UpdateResult:
        """Take a ``truth`` sample as the estimate; ignore every other sensor."""
        sensor = measurement.sensor
        counts = self._counts.setdefault(sensor, SensorCounts())
        if sensor != TRUTH:
            counts.ignored += 1
            return UpdateResult(False, math.nan, 0, IGNORED)
        missing = [name for name in TRUTH_STATE_NAMES if name not in measurement.names]
        if missing:
            raise ValueError(f"truth measurement lacks {', '.join(missing)}")
        values = np.array([measurement[name] for name in TRUTH_STATE_NAMES])
        dim = len(TRUTH_STATE_NAMES)
        t_s = float(measurement.t_s)
        if not (math.isfinite(t_s) and np.isfinite(values).all()):
            counts.rejected_nonfinite += 1
            return UpdateResult(False, math.nan, dim, NON_FINITE)
        if is_stale(self._t_s, t_s):
            counts.rejected_stale += 1
            return UpdateResult(False, math.nan, dim, STALE)
        for name in _ANGLE_NAMES:
            index = TRUTH_STATE_NAMES.index(name)
            values[index] = wrap_angle(values[index])
        self._mean = values
        self._t_s = max(self._t_s, t_s)
        counts.accepted += 1
        return UpdateResult(True, 0.0, dim, ACCEPTED)

    def estimate(self) -> Estimate:
        names = TRUTH_STATE_NAMES
        return Estimate(
            t_s=self._t_s,
            names=names,
            mean=self._mean.copy(),
            covariance=np.zeros((len(names), len(names))),
        )

    def estimate_at(self, t_s: float) -> Estimate:
        """The last truth extrapolated to ``t_s`` (:meth:`predict`), leaving the estimator
        as it was (for observers: the log, the metrics)."""
        mean, t0_s = self._mean, self._t_s
        try:
            self.predict(t_s)
            return self.estimate()
        finally:
            self._mean, self._t_s = mean, t0_s

    def counts(self) -> dict[str, dict[str, int]]:
        """Per sensor: accepted, rejected (by cause) and ignored samples."""
        return {sensor: dataclasses.asdict(c) for sensor, c in sorted(self._counts.items())}
