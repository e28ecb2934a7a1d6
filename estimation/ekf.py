"""The extended Kalman filter: CTRA process model, asynchronous multi-rate fusion.

Built on filterpy's :class:`~filterpy.kalman.ExtendedKalmanFilter`: the nonlinear
prediction of the mean goes through its ``predict_x`` and the covariance through its
``P = F P F' + Q``; updates go through its ``update`` (Joseph form). What this module adds:

- the models of :mod:`estimation.models` (CasADi-built Jacobians and process noise);
- time: every measurement is fused at its own time stamp; the filter predicts to it in
  sub-steps of at most ``config.max_step_s`` and refuses to go back;
- per-measurement checks: non-finite values are rejected (never fused), stale measurements
  (older than the filter) are rejected, the normalised innovation squared (NIS) is tested
  against a chi-square gate, jointly and, if that fails, channel by channel; a channel that
  fails for ``gate_release_s`` is believed again (its jump is given room in P first);
  every outcome is counted per sensor;
- hygiene: yaw wrapped to (-pi, pi], angle innovations wrapped, P kept symmetric.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter
from scipy.stats import chi2

from cosim.exceptions import ConfigError
from cosim.initial_state import InitialState
from cosim.records import Estimate, Measurement
from cosim.vehicle_params import VehicleParams
from estimation.config import EstimatorConfig
from estimation.errors import EstimatorError
from estimation.models import (
    ANGLE_STATES,
    MAX_STEP_S,
    STATE_NAMES,
    MeasurementModel,
    ProcessModel,
    ProcessNoise,
    build_measurement_models,
    state_index,
    wrap_angle,
)
from estimation.timing import forward_interval_s, is_stale
from estimation.update_result import (
    ACCEPTED,
    GATE,
    GATE_RELEASED,
    IGNORED,
    INVALID,
    NON_FINITE,
    PARTIAL,
    STALE,
    SensorCounts,
    UpdateResult,
)


@dataclass(frozen=True)
class _Selection:
    """Which channels of a measurement (by its names) the filter fuses, and how."""

    model_rows: tuple[int, ...]
    measurement_columns: tuple[int, ...]
    angle_rows: tuple[int, ...]
    model_variance: np.ndarray


@dataclass(frozen=True)
class _Innovation:
    """One (group of) channel(s) linearised at the current state, ready to gate and fuse."""

    z: np.ndarray
    h: np.ndarray
    jacobian: np.ndarray
    r: np.ndarray
    innovation: np.ndarray
    nis: float
    residual: Callable[[np.ndarray, np.ndarray], np.ndarray]


class _CtraKalmanFilter(ExtendedKalmanFilter):
    """filterpy's EKF whose state prediction is one CTRA sub-step of the process model."""

    def __init__(self, process: ProcessModel) -> None:
        super().__init__(dim_x=len(STATE_NAMES), dim_z=1)
        self._process = process
        self._x_next = self.x

    def predict_substep(self, dt_s: float) -> None:
        """Propagate mean and covariance over ``dt_s`` (at most the model's sub-step)."""
        self._x_next, self.F, self.Q = self._process.step(self.x, dt_s)
        self.predict()

    def predict_x(self, u: object = 0) -> None:
        """The nonlinear mean prediction, computed by :meth:`predict_substep`."""
        self.x = self._x_next


class Ekf:
    """Extended Kalman filter over :data:`estimation.models.STATE_NAMES`.

    ``initial`` sets the mean (position, yaw, forward speed; the rest zero, the rolling-radius
    scale one) and ``config`` its standard deviations; ``belief`` gives the wheel radius and
    track the wheel-speed model needs. ``t0_s`` is the time of the initial belief.
    """

    required_sensors: tuple[str, ...] = ("gnss",)
    """Sensors without which the filter cannot work (GNSS alone makes every state observable)."""

    supported_sensors: tuple[str, ...] = ("gnss", "imu", "wheel_speed", "heading")
    """Sensors the filter fuses; measurements of any other sensor are ignored."""

    state_names: tuple[str, ...] = STATE_NAMES

    def __init__(
        self,
        config: EstimatorConfig,
        initial: InitialState,
        belief: VehicleParams,
        *,
        t0_s: float = 0.0,
    ) -> None:
        if not math.isfinite(t0_s):
            raise ValueError(f"t0_s = {t0_s!r}: expected a finite time")
        if not 0.0 < config.max_step_s <= MAX_STEP_S:
            raise ConfigError(
                f"estimator.max_step_s = {config.max_step_s!r}: expected a number in "
                f"(0, {MAX_STEP_S:g}]"
            )
        self._config = config
        noise = ProcessNoise(
            position_psd_m2ps=config.position_psd_m2ps,
            yaw_psd_rad2ps=config.yaw_psd_rad2ps,
            lateral_accel_psd_m2ps3=config.lateral_accel_psd_m2ps3,
            yaw_accel_psd_rad2ps3=config.yaw_accel_psd_rad2ps3,
            jerk_psd_m2ps5=config.jerk_psd_m2ps5,
            rolling_radius_scale_psd_1ps=config.rolling_radius_scale_psd_1ps,
        )
        self._process = ProcessModel(noise, config.lateral_velocity_time_constant_s)
        self._models: dict[str, MeasurementModel] = build_measurement_models(
            belief,
            wheel_model_sigma_mps=config.wheel_model_sigma_mps,
            lateral_accel_model_sigma_mps2=config.lateral_accel_model_sigma_mps2,
        )
        self._angle_indices = tuple(state_index(name) for name in ANGLE_STATES)

        mean = {
            "x_m": initial.x_m,
            "y_m": initial.y_m,
            "yaw_rad": wrap_angle(initial.yaw_rad),
            "vx_mps": initial.speed_mps,
            "vy_mps": 0.0,
            "yaw_rate_radps": 0.0,
            "ax_mps2": 0.0,
            "rolling_radius_scale": 1.0,
        }
        sigma = {
            "x_m": config.init_position_sigma_m,
            "y_m": config.init_position_sigma_m,
            "yaw_rad": config.init_yaw_sigma_rad,
            "vx_mps": config.init_speed_sigma_mps,
            "vy_mps": config.init_lateral_speed_sigma_mps,
            "yaw_rate_radps": config.init_yaw_rate_sigma_radps,
            "ax_mps2": config.init_accel_sigma_mps2,
            "rolling_radius_scale": config.init_rolling_radius_scale_sigma,
        }
        self._kf = _CtraKalmanFilter(self._process)
        self._kf.x = np.array([[float(mean[name])] for name in STATE_NAMES])
        self._kf.P = np.diag([float(sigma[name]) ** 2 for name in STATE_NAMES])
        self._t_s = float(t0_s)

        self._counts: dict[str, SensorCounts] = {}
        self._gate_thresholds: dict[int, float] = {}
        self._gate_failing_since_s: dict[tuple[str, tuple[str, ...]], float] = {}
        self._selections: dict[tuple[str, tuple[str, ...]], _Selection] = {}

    # ----------------------------------------------------------------------------- queries

    @property
    def t_s(self) -> float:
        """Time of the current belief."""
        return self._t_s

    def estimate(self) -> Estimate:
        """The current belief (copies: later steps do not change it)."""
        return Estimate(
            t_s=self._t_s,
            names=STATE_NAMES,
            mean=self._kf.x.reshape(-1).copy(),
            covariance=self._kf.P.copy(),
        )

    def counts(self) -> dict[str, dict[str, int]]:
        """Per sensor: accepted, rejected (by cause), ignored and gate-released updates."""
        return {sensor: dataclasses.asdict(c) for sensor, c in sorted(self._counts.items())}

    def gate_threshold(self, dim: int) -> float:
        """The NIS above which a ``dim``-channel update is rejected (chi-square quantile)."""
        if dim < 1:
            raise ValueError(f"dim = {dim}: expected at least one channel")
        if dim not in self._gate_thresholds:
            self._gate_thresholds[dim] = float(chi2.ppf(self._config.gate_probability, dim))
        return self._gate_thresholds[dim]

    # ----------------------------------------------------------------------------- predict

    def predict(self, t_s: float) -> None:
        """Propagate the belief to ``t_s`` (no-op at the current time; never backwards)."""
        interval_s = forward_interval_s(self._t_s, float(t_s), "filter")
        if interval_s == 0.0:
            return
        substeps = max(1, math.ceil(interval_s / self._config.max_step_s - 1e-9))
        dt_s = interval_s / substeps
        for _ in range(substeps):
            self._kf.predict_substep(dt_s)
        self._t_s = float(t_s)
        self._normalise()
        if not self._is_finite():
            raise EstimatorError(
                f"EKF prediction to t_s = {t_s} s produced a non-finite state or covariance"
            )

    # ------------------------------------------------------------------------------ update

    def update(self, measurement: Measurement) -> UpdateResult:
        """Fuse one measurement at its own time (predicting to it first).

        Measurements of sensors the filter does not model are ignored (``accepted=False``,
        counted as ``ignored``). Non-finite, stale and gated measurements are rejected and
        counted; they never touch the state. Independent channels are gated one by one: a
        measurement with some channels gated is ``accepted`` with reason ``"partial"``, and
        its ``nis``/``dim`` are those of the fused channels.
        """
        sensor = measurement.sensor
        counts = self._counts.setdefault(sensor, SensorCounts())
        model = self._models.get(sensor)
        if model is None:
            counts.ignored += 1
            return UpdateResult(False, math.nan, 0, IGNORED)
        selection = self._selection(model, tuple(measurement.names))
        dim = len(selection.model_rows)
        if dim == 0:
            counts.ignored += 1
            return UpdateResult(False, math.nan, 0, IGNORED)

        values = np.asarray(measurement.values, dtype=float).reshape(-1)
        covariance = np.asarray(measurement.covariance, dtype=float)
        size = len(measurement.names)
        if values.shape != (size,) or covariance.shape != (size, size):
            raise ValueError(
                f"{sensor} measurement: {size} names but values of shape {values.shape} and "
                f"covariance of shape {covariance.shape}"
            )
        columns = list(selection.measurement_columns)
        z = values[columns]
        r_matrix = covariance[np.ix_(columns, columns)] + np.diag(selection.model_variance)
        t_s = float(measurement.t_s)
        if not (math.isfinite(t_s) and np.isfinite(z).all() and np.isfinite(r_matrix).all()):
            counts.rejected_nonfinite += 1
            return UpdateResult(False, math.nan, dim, NON_FINITE)
        if is_stale(self._t_s, t_s):
            counts.rejected_stale += 1
            return UpdateResult(False, math.nan, dim, STALE)

        self.predict(t_s)
        everything = tuple(range(dim))
        joint = self._innovation(model, selection, everything, z, r_matrix)
        if joint is None:
            counts.rejected_invalid += 1
            return UpdateResult(False, math.nan, dim, INVALID)
        if not self._config.gate or joint.nis <= self.gate_threshold(dim):
            # The common case: one joint update.
            self._forget_gate_failures(model, selection, everything)
            if not self._apply(joint):
                counts.rejected_invalid += 1
                return UpdateResult(False, joint.nis, dim, INVALID)
            counts.accepted += 1
            return UpdateResult(True, joint.nis, dim, ACCEPTED)

        # Above the gate. Independent channels (diagonal R) are then gated one by one and
        # fused sequentially, so a spinning wheel or a lateral-acceleration transient costs
        # only its own channel (for a linear model sequential fusion equals the joint
        # update: Bar-Shalom, Li, Kirubarajan 2001, section 3.3.2). Correlated channels
        # stay one group.
        if np.any(r_matrix - np.diag(np.diag(r_matrix))):
            groups = [everything]
        else:
            groups = [(i,) for i in everything]
        fused_nis, fused_dim, tested_nis = 0.0, 0, 0.0
        gated = released = invalid = 0
        for group in groups:
            outcome, nis = self._gate_and_fuse(model, selection, group, z, r_matrix, t_s)
            if math.isfinite(nis):
                tested_nis += nis
            if outcome in (ACCEPTED, GATE_RELEASED):
                fused_nis += nis
                fused_dim += len(group)
                released += outcome == GATE_RELEASED
            elif outcome == GATE:
                gated += len(group)
            else:
                invalid += 1
        counts.channels_gated += gated
        counts.gate_released += released
        if fused_dim == 0:
            if gated:
                counts.rejected_gate += 1
                return UpdateResult(False, tested_nis, dim, GATE)
            counts.rejected_invalid += 1
            return UpdateResult(False, math.nan, dim, INVALID)
        counts.accepted += 1
        if gated or invalid:
            return UpdateResult(True, fused_nis, fused_dim, PARTIAL)
        return UpdateResult(True, fused_nis, fused_dim, GATE_RELEASED if released else ACCEPTED)

    def _innovation(
        self,
        model: MeasurementModel,
        selection: _Selection,
        group: tuple[int, ...],
        z: np.ndarray,
        r_matrix: np.ndarray,
    ) -> _Innovation | None:
        """The innovation of the channels ``group`` (indices into ``z``) at the current state.

        ``None`` if its covariance is not positive definite.
        """
        h_all, jacobian_all = model.evaluate(self._kf.x)
        index = list(group)
        rows = [selection.model_rows[i] for i in index]
        h = h_all[rows]
        jacobian = jacobian_all[rows, :]
        z_group = z[index]
        r_group = r_matrix[np.ix_(index, index)]
        residual = _residual_function(
            tuple(j for j, i in enumerate(group) if i in selection.angle_rows)
        )
        innovation = residual(z_group, h)
        s_matrix = jacobian @ self._kf.P @ jacobian.T + r_group
        s_matrix = 0.5 * (s_matrix + s_matrix.T)
        if len(group) == 1:
            if not s_matrix[0, 0] > 0.0:
                return None
            nis = float(innovation[0] ** 2 / s_matrix[0, 0])
        else:
            try:
                cholesky = np.linalg.cholesky(s_matrix)
            except np.linalg.LinAlgError:
                return None
            whitened = np.linalg.solve(cholesky, innovation)
            nis = float(whitened @ whitened)
        return _Innovation(z_group, h, jacobian, r_group, innovation, nis, residual)

    def _apply(self, innovation: _Innovation) -> bool:
        """Fuse an innovation with filterpy's update; undo and return False if non-finite."""
        x_before, p_before = self._kf.x.copy(), self._kf.P.copy()
        residual = innovation.residual
        self._kf.update(
            innovation.z.reshape(-1, 1),
            HJacobian=lambda _x: innovation.jacobian,
            Hx=lambda _x: innovation.h.reshape(-1, 1),
            R=innovation.r,
            residual=lambda a, b: residual(a.reshape(-1), b.reshape(-1)).reshape(-1, 1),
        )
        self._normalise()
        if not self._is_finite():
            self._kf.x, self._kf.P = x_before, p_before
            return False
        return True

    def _gate_and_fuse(
        self,
        model: MeasurementModel,
        selection: _Selection,
        group: tuple[int, ...],
        z: np.ndarray,
        r_matrix: np.ndarray,
        t_s: float,
    ) -> tuple[str, float]:
        """Gate and fuse the channels ``group`` on their own: outcome and NIS."""
        innovation = self._innovation(model, selection, group, z, r_matrix)
        if innovation is None:
            return INVALID, math.nan
        outcome = ACCEPTED
        key = self._gate_key(model, selection, group)
        if innovation.nis > self.gate_threshold(len(group)):
            since_s = self._gate_failing_since_s.setdefault(key, t_s)
            if t_s - since_s < self._config.gate_release_s:
                return GATE, innovation.nis
            outcome = GATE_RELEASED
            self._inflate_for_jump(innovation.jacobian, innovation.innovation)
        else:
            self._gate_failing_since_s.pop(key, None)
        if not self._apply(innovation):
            return INVALID, innovation.nis
        return outcome, innovation.nis

    @staticmethod
    def _gate_key(
        model: MeasurementModel, selection: _Selection, group: tuple[int, ...]
    ) -> tuple[str, tuple[str, ...]]:
        """Which channels a run of gate failures belongs to (for ``gate_release_s``)."""
        return model.sensor, tuple(model.channels[selection.model_rows[i]] for i in group)

    def _forget_gate_failures(
        self, model: MeasurementModel, selection: _Selection, group: tuple[int, ...]
    ) -> None:
        if self._gate_failing_since_s:
            self._gate_failing_since_s.pop(self._gate_key(model, selection, group), None)
            for i in group:
                self._gate_failing_since_s.pop(self._gate_key(model, selection, (i,)), None)

    # ----------------------------------------------------------------------------- helpers

    def _inflate_for_jump(self, jacobian: np.ndarray, innovation: np.ndarray) -> None:
        """Make room for a persistent jump before a gate-released update.

        A sensor that has disagreed for ``gate_release_s`` is believed: the state is taken
        to have jumped. The covariance grows by ``G y y' G'`` with ``G = D H' (H D H')^-1``
        and ``D = diag(P)``: the jump ``y`` is explained by the states the channels observe,
        shared in proportion to their variances (a GNSS jump moves the position only, not
        the speed through its correlation with the position). Afterwards the innovation has
        NIS ``n / (1 + n)`` < 1 and the update fuses it as an ordinary measurement.
        """
        spread = np.diag(self._kf.P)[:, None] * jacobian.T
        gain = spread @ np.linalg.inv(jacobian @ spread)
        jump = gain @ innovation
        self._kf.P = self._kf.P + np.outer(jump, jump)

    def _selection(self, model: MeasurementModel, names: tuple[str, ...]) -> _Selection:
        key = (model.sensor, names)
        if key not in self._selections:
            model_rows, columns = model.select(names)
            angle_rows = tuple(
                i for i, row in enumerate(model_rows) if model.channels[row] in model.angle_channels
            )
            variance = np.array([model.model_sigma[row] ** 2 for row in model_rows])
            self._selections[key] = _Selection(model_rows, columns, angle_rows, variance)
        return self._selections[key]

    def _normalise(self) -> None:
        """Wrap the angle states and symmetrise the covariance."""
        for index in self._angle_indices:
            self._kf.x[index, 0] = wrap_angle(self._kf.x[index, 0])
        self._kf.P = 0.5 * (self._kf.P + self._kf.P.T)

    def _is_finite(self) -> bool:
        return bool(np.isfinite(self._kf.x).all() and np.isfinite(self._kf.P).all())


def _residual_function(
    angle_rows: tuple[int, ...],
) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """``z - h`` with the angle channels wrapped to (-pi, pi]."""

    def residual(z: np.ndarray, h: np.ndarray) -> np.ndarray:
        difference = np.asarray(z, dtype=float) - np.asarray(h, dtype=float)
        for row in angle_rows:
            difference[row] = wrap_angle(difference[row])
        return difference

    return residual
