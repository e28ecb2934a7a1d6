"""The extended Kalman filter: dynamic-bicycle process model, asynchronous multi-rate fusion.

Built on filterpy's :class:`~filterpy.kalman.ExtendedKalmanFilter`: the nonlinear
prediction of the mean goes through its ``predict_x`` and the covariance through its
``P = F P F' + Q``; updates go through its ``update`` (Joseph form). The models and their
exact Jacobians come from :mod:`estimation.models` (CasADi); when and whether a measurement
is fused (time, gating, rejection, counters) from :class:`estimation.fusion.KalmanFusion`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter

from estimation.fusion import KalmanFusion, TrialUpdate
from estimation.models import STATE_NAMES, MeasurementModel, ProcessModel


class _BicycleKalmanFilter(ExtendedKalmanFilter):
    """filterpy's EKF whose state prediction is one RK4 sub-step of the process model."""

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


class Ekf(KalmanFusion):
    """Extended Kalman filter over :data:`estimation.models.STATE_NAMES`.

    See :class:`estimation.fusion.KalmanFusion` for the arguments and the contract.
    """

    kind = "EKF"

    def _setup_filter(self, mean: np.ndarray, covariance: np.ndarray) -> None:
        self._kf = _BicycleKalmanFilter(self._process)
        self._kf.x = mean.reshape(-1, 1).copy()
        self._kf.P = covariance.copy()

    @property
    def _x(self) -> np.ndarray:
        return self._kf.x.reshape(-1)

    def _set_mean(self, mean: np.ndarray) -> None:
        self._kf.x = np.asarray(mean, dtype=float).reshape(-1, 1)

    @property
    def _p(self) -> np.ndarray:
        return self._kf.P

    def _set_covariance(self, covariance: np.ndarray) -> None:
        self._kf.P = covariance

    def _predict_substep(self, dt_s: float) -> None:
        self._kf.predict_substep(dt_s)

    def _trial_update(
        self,
        model: MeasurementModel,
        rows: tuple[int, ...],
        z: np.ndarray,
        r_matrix: np.ndarray,
        residual: Callable[[np.ndarray, np.ndarray], np.ndarray],
        angle_rows: tuple[int, ...],
    ) -> TrialUpdate:
        """filterpy's EKF update (Joseph form) with the model linearised at the mean."""
        del angle_rows  # the residual wraps them
        kf = self._kf
        x_before, p_before = kf.x, kf.P
        h_all, jacobian_all = model.evaluate(kf.x)
        index = list(rows)
        h = h_all[index].reshape(-1, 1)
        jacobian = jacobian_all[index, :]
        try:
            kf.update(
                np.asarray(z, dtype=float).reshape(-1, 1),
                HJacobian=lambda _x: jacobian,
                Hx=lambda _x: h,
                R=r_matrix,
                residual=lambda a, b: residual(a.reshape(-1), b.reshape(-1)).reshape(-1, 1),
            )
            return TrialUpdate(
                innovation=kf.y.reshape(-1).copy(),
                innovation_covariance=np.array(kf.S, dtype=float),
                mean=kf.x.reshape(-1).copy(),
                covariance=kf.P.copy(),
            )
        finally:
            kf.x, kf.P = x_before, p_before
