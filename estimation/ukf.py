"""The unscented Kalman filter: the EKF's state and models, propagated by sigma points.

Built on filterpy's :class:`~filterpy.kalman.UnscentedKalmanFilter` with Van der Merwe's
scaled sigma points (:class:`~filterpy.kalman.MerweScaledSigmaPoints`; Van der Merwe, "Sigma-
Point Kalman Filters for Probabilistic Inference in Dynamic State-Space Models", PhD thesis,
2004, section 3.2.2). It shares with :class:`estimation.ekf.Ekf` the state, the CasADi
process and measurement models of :mod:`estimation.process_model` and
:mod:`estimation.measurement_models` (evaluated numerically at the sigma points, each model
mapped over all of them in one call, as C with ``estimator.compiled``) and everything about
when and whether a measurement is fused (:class:`estimation.fusion.KalmanFusion`). The
sigma points and the update are filterpy's algorithms written out on arrays
(:class:`ScaledSigmaPoints`, :meth:`Ukf._trial_update`): the same numbers to the bit,
without filterpy's loops over the points in Python.

Differences from the EKF, all about the unscented transform:

- the process noise of a sub-step is the same Van Loan integral as the EKF's, evaluated at
  the prior mean (it is added after the transform, as filterpy does);
- yaw: the propagated sigma points' yaws are unwrapped around the first point's before the
  transform, so that plain means and differences are exact (the spread of the points is far
  below pi), and the mean is wrapped afterwards; angle channels of a measurement are
  averaged on the circle (weighted mean of ``sin``/``cos``) and differenced wrapped;
- before every update the sigma points are drawn afresh from the current belief (filterpy
  reuses those of the last prediction, which would be stale after an earlier update at the
  same time);
- the jump inflation of a gate release uses the measurement model's Jacobian at the mean.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import casadi as ca
import numpy as np
from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter, unscented_transform
from scipy.linalg.lapack import dpotrf as _potrf

from cosim.core.dense_function import DenseFunction
from estimation.fusion import KalmanFusion
from estimation.innovation import TrialUpdate
from estimation.measurement_models import MeasurementModel
from estimation.process_model import ProcessModel
from estimation.state import ANGLE_STATES, STATE_NAMES, state_index


def _circular_mean_function(
    angle_columns: tuple[int, ...],
) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """Weighted mean of sigma points (one per row) with the columns ``angle_columns``
    averaged on the circle."""

    def mean(sigmas: np.ndarray, weights: np.ndarray) -> np.ndarray:
        result = np.dot(weights, sigmas)
        for column in angle_columns:
            result[column] = np.arctan2(
                np.dot(weights, np.sin(sigmas[:, column])),
                np.dot(weights, np.cos(sigmas[:, column])),
            )
        return result

    return mean


def _wrapped_difference_function(
    angle_columns: tuple[int, ...],
) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """``a - b`` with the columns ``angle_columns`` wrapped to [-pi, pi)."""

    def difference(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        result = np.subtract(a, b)
        for column in angle_columns:
            result[..., column] = _wrap(result[..., column])
        return result

    return difference


class ScaledSigmaPoints(MerweScaledSigmaPoints):
    """filterpy's :class:`~filterpy.kalman.MerweScaledSigmaPoints` with its points drawn in
    a few array operations: the same Cholesky factor (LAPACK's ``potrf`` of the upper
    triangle, as ``scipy.linalg.cholesky`` calls it) and the same subtractions ``x - (-U_k)``
    and ``x - U_k``, without filterpy's loop over the rows nor scipy's checks around the
    factorisation (a non-finite or indefinite covariance raises as there), so the same
    points to the bit (``tests/estimation/test_ukf_update.py``)."""

    def sigma_points(self, x: np.ndarray, P: np.ndarray) -> np.ndarray:  # noqa: N803
        n = self.n
        x = np.asarray(x, dtype=float).reshape(-1)
        if x.size != n:
            raise ValueError(f"expected size(x) {n}, but size is {x.size}")
        lambda_ = self.alpha**2 * (n + self.kappa) - n
        scaled = (lambda_ + n) * np.asarray(P, dtype=float)
        if not np.isfinite(scaled).all():
            raise ValueError("array must not contain infs or NaNs")
        root, info = _potrf(scaled, lower=0, clean=1)
        if info > 0:
            raise np.linalg.LinAlgError(
                f"{info}-th leading minor of the array is not positive definite")
        if info < 0:
            raise ValueError(f"LAPACK reported an illegal value in {-info}-th argument "
                             'on entry to "POTRF".')
        sigmas = np.empty((2 * n + 1, n))
        sigmas[0] = x
        np.subtract(x, -root, out=sigmas[1:n + 1])
        np.subtract(x, root, out=sigmas[n + 1:])
        return sigmas


class _BicycleUnscentedFilter(UnscentedKalmanFilter):
    """filterpy's UKF whose sigma points go through the process model in one mapped call,
    with angles unwrapped around the first sigma point and a vectorised cross covariance."""

    def __init__(self, process: ProcessModel, points: MerweScaledSigmaPoints) -> None:
        super().__init__(
            dim_x=len(STATE_NAMES),
            dim_z=1,
            dt=0.0,
            hx=None,
            fx=None,
            points=points,
        )
        self._process = process
        self._angles = [state_index(name) for name in ANGLE_STATES]

    def compute_process_sigmas(self, dt: float, fx: object = None,
                               command_rad: float | None = None) -> None:
        """Draw the sigma points of the current belief and propagate them all at once, the
        steering driven by ``command_rad`` (None: none; filterpy passes its ``fx_args``)."""
        del fx
        sigmas = self._process.propagate(self.points_fn.sigma_points(self.x, self.P), dt,
                                         command_rad)
        reference = sigmas[0, self._angles]
        sigmas[:, self._angles] = reference + _wrap(sigmas[:, self._angles] - reference)
        self.sigmas_f = sigmas

    def cross_variance(
        self, x: np.ndarray, z: np.ndarray, sigmas_f: np.ndarray, sigmas_h: np.ndarray
    ) -> np.ndarray:
        """``sum_i Wc_i (X_i - x)(Z_i - z)'`` in one product (filterpy loops in Python)."""
        dx = self.residual_x(sigmas_f, x)
        dz = self.residual_z(sigmas_h, z)
        return (dx * self.Wc[:, None]).T @ dz


@functools.lru_cache(maxsize=32)
def at_points(function: ca.Function, count: int) -> ca.Function:
    """``function(x, belief)`` (a measurement model's ``h``) of ``count`` points at once:
    ``(x: n x count, belief) -> h: m x count``, CasADi's map of the function over the
    points (the belief shared), each column evaluated as one call is, so the same numbers;
    built once per process per model and count."""
    return function.map(f"{function.name()}_at_{count}", "serial", count, [1], [])


def _wrap(angle_rad: np.ndarray) -> np.ndarray:
    """Angles wrapped to [-pi, pi) (vectorised; for differences, where the end is moot)."""
    return (angle_rad + np.pi) % (2.0 * np.pi) - np.pi


class Ukf(KalmanFusion):
    """Unscented Kalman filter over :data:`estimation.state.STATE_NAMES`.

    Sigma points: ``config.ukf_alpha``, ``ukf_beta``, ``ukf_kappa`` (Van der Merwe's alpha,
    beta, kappa). The defaults (1, 2, 0) give all-positive weights (no negative centre
    weight, so the transformed covariance stays positive semi-definite) and points at
    ``sqrt(n)`` standard deviations. See :class:`estimation.fusion.KalmanFusion` for the
    rest of the contract.
    """

    kind = "UKF"

    def _sigma_point_count(self) -> int:
        return 2 * len(STATE_NAMES) + 1

    def _setup_filter(self, mean: np.ndarray, covariance: np.ndarray) -> None:
        self._points = ScaledSigmaPoints(
            n=len(STATE_NAMES),
            alpha=self._config.ukf_alpha,
            beta=self._config.ukf_beta,
            kappa=self._config.ukf_kappa,
        )
        self._kf = _BicycleUnscentedFilter(self._process, self._points)
        self._kf.x = mean.copy()
        self._kf.P = covariance.copy()

    @property
    def _x(self) -> np.ndarray:
        return self._kf.x

    def _set_mean(self, mean: np.ndarray) -> None:
        self._kf.x = np.asarray(mean, dtype=float).reshape(-1)

    @property
    def _p(self) -> np.ndarray:
        return self._kf.P

    def _set_covariance(self, covariance: np.ndarray) -> None:
        self._kf.P = covariance

    def _predict_one(self, t0_s: float, t1_s: float, dt_s: float,
                     command_rad: float | None) -> None:
        """filterpy's predict through sigma points (the process noise linearised at the
        mean), between the acceleration's move and the angles' wrap
        (:meth:`KalmanFusion._predict_one`)."""
        self._follow_accel_command(t0_s, t1_s)
        self._kf.Q = self._process.process_noise(self._kf.x, dt_s, command_rad)
        self._kf.predict(dt_s, command_rad=command_rad)
        self._normalise()

    def _trial_update(
        self,
        model: MeasurementModel,
        rows: tuple[int, ...],
        z: np.ndarray,
        r_matrix: np.ndarray,
        residual: Callable[[np.ndarray, np.ndarray], np.ndarray],
        angle_rows: tuple[int, ...],
    ) -> TrialUpdate:
        """filterpy's UKF update (``UnscentedKalmanFilter.update``) through sigma points
        drawn from the current belief, written out on arrays: the measurement model at
        every sigma point in one call (:func:`at_points`), then filterpy's unscented
        transform and its gain, step by step as filterpy takes them (the same numbers,
        ``tests/estimation/test_ukf_update.py``), without changing the belief."""
        del residual  # the same, vectorised: _wrapped_difference_function
        kf = self._kf
        kf.sigmas_f = sigmas = self._points.sigma_points(kf.x, kf.P)
        # C-ordered as filterpy's list of points is: numpy's products then sum alike
        at_sigmas = self._sigma_models[model.sensor].rows(sigmas)[0]
        sigmas_h = np.ascontiguousarray(at_sigmas[:, list(rows)])
        if angle_rows:
            kf.z_mean = _circular_mean_function(angle_rows)
            kf.residual_z = _wrapped_difference_function(angle_rows)
        else:
            kf.z_mean, kf.residual_z = None, np.subtract
        zp, s = unscented_transform(sigmas_h, kf.Wm, kf.Wc, r_matrix, kf.z_mean,
                                    kf.residual_z)
        gain = np.dot(kf.cross_variance(kf.x, zp, sigmas, sigmas_h), np.linalg.inv(s))
        innovation = kf.residual_z(np.asarray(z, dtype=float).reshape(-1), zp)
        return TrialUpdate(
            innovation=np.asarray(innovation, dtype=float).reshape(-1),
            innovation_covariance=s,
            mean=np.add(kf.x, np.dot(gain, innovation)),
            covariance=kf.P - np.dot(gain, np.dot(s, gain.T)),
        )

    @functools.cached_property
    def _sigma_models(self) -> dict[str, DenseFunction]:
        """Each measurement model's :func:`at_points` on buffers of this filter's own, the
        model's belief set once."""
        count = self._sigma_point_count()
        return {sensor: DenseFunction(at_points(model.value_function.function, count),
                                      parameters=model.value_function.parameters)
                for sensor, model in self._models.items()}

    def _hot_functions(self) -> tuple[DenseFunction, ...]:
        """The process noise and the sub-step of every sigma point, and every measurement
        model at every sigma point: what the UKF evaluates at every step."""
        return (*self._process.sigma_point_functions(), *self._sigma_models.values())
