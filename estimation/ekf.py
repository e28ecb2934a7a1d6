"""The extended Kalman filter: dynamic-bicycle process model, asynchronous multi-rate fusion.

The algorithm of filterpy's :class:`~filterpy.kalman.ExtendedKalmanFilter`: the nonlinear
prediction of the mean, the covariance through ``P = F P F' + Q`` (both in one CasADi
function with the sub-step, :meth:`estimation.process_model.ProcessModel.covariance_step`),
updates in Joseph form (:func:`joseph_update`), written
out on the filter's own mean and covariance: filterpy's methods also store copies of
every intermediate on the filter object at each call, which cost more than the algebra of
a 17-state filter fed at 300 Hz, and importing filterpy imports ``scipy.stats`` (a third
of a second of every process start). ``tests/estimation/test_ekf_update.py`` checks both
functions against filterpy's. The models and their exact Jacobians come from
:mod:`estimation.process_model` and :mod:`estimation.measurement_models` (CasADi); when and
whether a measurement is fused (time, gating, rejection, counters) from
:class:`estimation.fusion.KalmanFusion`.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from cosim.core.dense_function import DenseFunction
from estimation.fusion import KalmanFusion
from estimation.innovation import CheckedMeasurement, Selection, TrialUpdate, residual_function
from estimation.joint_update import JointPosterior, JointUpdate
from estimation.measurement_models import MeasurementModel


class Ekf(KalmanFusion):
    """Extended Kalman filter over :data:`estimation.state.STATE_NAMES`.

    See :class:`estimation.fusion.KalmanFusion` for the arguments and the contract.
    """

    kind = "EKF"

    def _setup_filter(self, mean: np.ndarray, covariance: np.ndarray) -> None:
        self._mean = np.array(mean, dtype=float).reshape(-1)
        self._covariance = np.array(covariance, dtype=float)

    @property
    def _x(self) -> np.ndarray:
        return self._mean

    def _set_mean(self, mean: np.ndarray) -> None:
        self._mean = np.asarray(mean, dtype=float).reshape(-1)

    @property
    def _p(self) -> np.ndarray:
        return self._covariance

    def _set_covariance(self, covariance: np.ndarray) -> None:
        self._covariance = covariance

    def _hot_functions(self) -> tuple[DenseFunction, ...]:
        """The sub-step of the process model, every measurement model's ``h`` with its
        Jacobian, and the joint update of an instant's measurements: the EKF's whole
        evaluation of its models."""
        return (*self._process.compiled_functions(),
                *(model.function for model in self._models.values()),
                self._joint_function.function)

    @functools.cached_property
    def _joint_function(self) -> JointUpdate:
        """The joint update over every channel of the models (:mod:`estimation.joint_update`)."""
        beliefs = [model.function.parameters for model in self._models.values()]
        belief = beliefs[0]
        if belief is None or any(b is None or not np.array_equal(b, belief) for b in beliefs):
            raise ValueError("the measurement models must share one belief")
        return JointUpdate(self._models, belief, self._recorded_library)

    def _joint_update(self, checked: list[CheckedMeasurement]) -> JointPosterior | None:
        """The iterated EKF's update (Bell and Cathey, "The iterated Kalman filter update as
        a Gauss-Newton method", IEEE TAC 1993; Bar-Shalom, Li, Kirubarajan 2001, section
        10.3.2): the models are linearised at the prior mean, and again at the posterior as
        long as the update's linearisation error
        (:attr:`estimation.joint_update.JointPosterior.linearisation_error`) exceeds
        ``estimator.ekf_linearisation_tolerance`` standard deviations of the measurement
        noise, at most ``estimator.ekf_iterations`` times. Where the models are nearly linear
        over the step (almost every instant) the first update stands as the plain EKF's;
        where they are not (the first instant of a run, its prior drawn with a road-wheel
        angle a few degrees off, which puts the bicycle's tyres at slip angles the car does
        not have), one linearisation at the prior gave the lateral acceleration's innovation
        to the wrong states and the filter gated the steering sensor for the next tenth of a
        second. The NIS are the first update's, against the prior (the gate's and the
        metrics' figure)."""
        first = self._linearised_update(checked, None)
        if first is None:
            return None
        best: JointPosterior = first
        latest: JointPosterior | None = first
        iterations = 0
        while (latest is not None and iterations < self._config.ekf_iterations
               and latest.linearisation_error > self._config.ekf_linearisation_tolerance):
            latest = self._linearised_update(checked, latest.mean)
            iterations += 1
            if latest is not None and latest.linearisation_error < best.linearisation_error:
                best = latest  # Gauss-Newton may oscillate: the most nearly linear one stands
        if best is first:
            return first
        return JointPosterior(best.mean, best.covariance, first.nis, best.linearisation_error,
                              best.symmetric, best.positive_definite)

    def _linearised_update(self, checked: list[CheckedMeasurement],
                           at: np.ndarray | None) -> JointPosterior | None:
        """One joint update with the models linearised at ``at`` (None: the prior mean): as
        compiled C (:mod:`estimation.joint_update`) when the models are compiled; otherwise
        in numpy (:meth:`_joint_trial_update`), which is then faster than the one function
        in CasADi's virtual machine."""
        joint = self._joint_function
        if not joint.function.compiled:
            return self._posterior(checked, at)
        return joint(self._mean, self._covariance,
                     [(c.model, c.selection, c.z) for c in checked], at)

    def _predict_one(self, t0_s: float, t1_s: float, dt_s: float,
                     command_rad: float | None) -> None:
        """The sub-step of :meth:`KalmanFusion._predict_one` as one function
        (:meth:`estimation.process_model.ProcessModel.covariance_step`): the acceleration
        moved by its commands, the RK4 sub-step of the mean, filterpy's ``P = F P F' + Q``,
        the angles wrapped and the covariance symmetrised."""
        self._mean, self._covariance = self._process.covariance_step(
            self._mean, self._covariance, dt_s, command_rad,
            self._accel_commands.increment(t0_s, t1_s))

    def _trial_update(
        self,
        model: MeasurementModel,
        rows: tuple[int, ...],
        z: np.ndarray,
        r_matrix: np.ndarray,
        residual: Callable[[np.ndarray, np.ndarray], np.ndarray],
        angle_rows: tuple[int, ...],
    ) -> TrialUpdate:
        """filterpy's EKF update (Joseph form) with the model linearised at the mean
        (:func:`joseph_update`, the algorithm of filterpy's ``update`` without its
        bookkeeping)."""
        del angle_rows  # the residual wraps them
        x = self._mean
        h_all, jacobian_all = model.evaluate(x)
        index = list(rows)
        return joseph_update(x, self._covariance, np.asarray(z, dtype=float).reshape(-1),
                             h_all[index], jacobian_all[index, :], r_matrix, residual)


    def _joint_trial_update(
        self, blocks: list[tuple[MeasurementModel, Selection, np.ndarray, np.ndarray]],
        at: np.ndarray | None = None,
    ) -> TrialUpdate:
        """Every block's channels in one Joseph update, each model linearised at ``at``
        (None: the mean; :mod:`estimation.joint_update`): the measurements stacked, their
        noise block-diagonal."""
        x = self._mean
        stacked = _stacked(blocks, x if at is None else at)
        values = stacked.values if at is None else stacked.values + stacked.jacobian @ (x - at)
        noise = block_diagonal([r_matrix for *_, r_matrix in blocks])
        return joseph_update(x, self._covariance, stacked.measured, values, stacked.jacobian,
                             noise, residual_function(stacked.angle_rows))

    def _posterior(self, checked: list[CheckedMeasurement],
                   at: np.ndarray | None) -> JointPosterior | None:
        """:meth:`_linearised_update` in numpy: the update, each measurement's NIS and the
        linearisation error, as the compiled function gives them."""
        posterior = super()._joint_update(checked, at)
        if posterior is None:
            return None
        blocks = [(c.model, c.selection, c.z, np.diag(c.selection.model_variance))
                  for c in checked]
        at = self._mean if at is None else at
        before, after = _stacked(blocks, at), _stacked(blocks, posterior.mean)
        miss = residual_function(before.angle_rows)(
            after.values, before.values + before.jacobian @ (posterior.mean - at))
        sigma = np.sqrt(np.concatenate([c.selection.model_variance for c in checked]))
        return JointPosterior(posterior.mean, posterior.covariance, posterior.nis,
                              float(np.max(np.abs(miss / sigma))))


@dataclass(frozen=True)
class _Stack:
    """Measurement models of several blocks evaluated at one point, their rows stacked."""

    values: np.ndarray
    jacobian: np.ndarray
    measured: np.ndarray
    angle_rows: tuple[int, ...]


def _stacked(blocks: list[tuple[MeasurementModel, Selection, np.ndarray, np.ndarray]],
             x: np.ndarray) -> _Stack:
    """The selected channels of every block's model at ``x``, stacked in order."""
    values, jacobians, measured, angle_rows = [], [], [], []
    offset = 0
    for model, selection, z, _ in blocks:
        h_all, jacobian_all = model.evaluate(x)
        rows = list(selection.model_rows)
        values.append(h_all[rows])
        jacobians.append(jacobian_all[rows, :])
        measured.append(np.asarray(z, dtype=float).reshape(-1))
        angle_rows += [offset + row for row in selection.angle_rows]
        offset += len(rows)
    return _Stack(np.concatenate(values), np.vstack(jacobians), np.concatenate(measured),
                  tuple(angle_rows))


def block_diagonal(blocks: list[np.ndarray]) -> np.ndarray:
    """The square blocks on the diagonal of one matrix, zeros elsewhere (what
    ``scipy.linalg.block_diag`` gives, without its general-purpose checks: a joint update
    builds one at every fused instant)."""
    size = sum(block.shape[0] for block in blocks)
    matrix = np.zeros((size, size))
    start = 0
    for block in blocks:
        end = start + block.shape[0]
        matrix[start:end, start:end] = block
        start = end
    return matrix


def joseph_update(
    x: np.ndarray,
    p: np.ndarray,
    z: np.ndarray,
    h: np.ndarray,
    jacobian: np.ndarray,
    r_matrix: np.ndarray,
    residual: Callable[[np.ndarray, np.ndarray], np.ndarray],
) -> TrialUpdate:
    """One EKF update, the algorithm of filterpy's ``ExtendedKalmanFilter.update``.

    ``S = H P H' + R``, ``K = P H' S^-1``, ``x+ = x + K y`` with ``y = residual(z, h)``,
    and the covariance in Joseph form ``P+ = (I - K H) P (I - K H)' + K R K'`` (valid for
    any gain and better conditioned than ``(I - K H) P``; Bar-Shalom, Li, Kirubarajan,
    "Estimation with Applications to Tracking and Navigation", Wiley 2001, eq. 5.2.3-18).
    filterpy's method does the same products and also stores copies of ``z``, ``x`` and
    ``P`` on the filter object at every call, which cost more than the algebra for a
    17-state filter fed at 300 Hz; ``tests/estimation/test_ekf.py`` checks that both give
    the same posterior.
    """
    pht = p @ jacobian.T
    s_matrix = jacobian @ pht + r_matrix
    gain = pht @ np.linalg.inv(s_matrix)
    innovation = residual(z, h)
    i_kh = np.eye(x.size) - gain @ jacobian
    return TrialUpdate(
        innovation=innovation,
        innovation_covariance=s_matrix,
        mean=x + gain @ innovation,
        covariance=i_kh @ p @ i_kh.T + gain @ r_matrix @ gain.T,
    )
