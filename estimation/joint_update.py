"""The EKF's update with every measurement of one instant, as one CasADi function.

At an instant when several sensors report (the IMU, wheel speeds and steering every 10 ms,
the GNSS every 50), the EKF fuses them in one update: the measurements stacked, their
noise block-diagonal, every model linearised at the prior mean (for a linearised model the
same posterior as fusing them one after another: Bar-Shalom, Li, Kirubarajan, "Estimation
with Applications to Tracking and Navigation", Wiley 2001, section 3.3.2). This module
poses that update once, symbolically, over the channels of *every* measurement model the
filter has, stacked in a fixed order; a ``mask`` input says which channels an instant
carries. With ``m`` the mask (1 for a channel present, 0 otherwise), ``h``/``H`` the
stacked models and their Jacobians at the prior mean ``x`` with covariance ``P``,
``z`` the measurements and ``r`` their variances:

    y = m .* wrap(z - h(x))           H_m = diag(m) H           R_m = diag(m .* r + 1 - m)
    S = H_m P H_m' + R_m              K = P H_m' S^-1
    x+ = x + K y                      P+ = (I - K H_m) P (I - K H_m)' + K R_m K'   (Joseph)
    NIS_j = y_j' S_jj^-1 y_j          for each model's block j (of the symmetrised S)

An absent channel's row of ``H_m`` and entry of ``y`` are exactly zero and its noise is 1,
so it adds nothing to ``K``, ``x+`` or ``P+`` (the same numbers as the update without it,
to rounding), and its block of ``S`` is the identity, so it adds nothing to the NIS.
``P+`` is symmetric by construction: both products of the Joseph form are computed on and
above the diagonal and mirrored (the numpy path symmetrises the full products instead; the
two agree to rounding). The angle channels' innovations are wrapped to (-pi, pi] as
:func:`estimation.state.wrap_angle` does.

The models may be linearised at a point ``x_l`` other than the prior mean (the iterated
EKF, :meth:`estimation.ekf.Ekf._joint_update`): then ``h(x)`` above is ``h(x_l) + H (x - x_l)``
with ``H`` the Jacobian at ``x_l`` (Bell and Cathey, "The iterated Kalman filter update as a
Gauss-Newton method", IEEE TAC 1993); at ``x_l = x`` this is the update above, to the bit.
The function also gives the largest linearisation error of the update, in standard
deviations of the measurement noise: ``max_j |h_j(x+) - h_j(x_l) - H_j (x+ - x_l)| / sqrt(r_j)``
over the channels present (angles wrapped), which says whether the models are linear enough
over the step ``x+ - x_l`` for the update to stand.

One function serves every combination of sensors and channels, and its numbers (the
belief) are an input: it is compiled to C once per machine with the filter's other models
(:func:`estimation.compiled_models.use_compiled`). Without a compiler it is not used: evaluated
by CasADi's virtual machine it costs more than the same algebra in numpy.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import numpy as np

from cosim.core.built_once import built_once
from cosim.core.compiled_function import external_function
from cosim.core.dense_function import DenseFunction
from estimation.innovation import Selection
from estimation.measurement_models import MeasurementModel
from estimation.state import STATE_NAMES, wrap_angle_symbolic

JOINT_FUNCTION = "ekf_joint_update"
"""The joint update's name, in the filter's compiled library."""


@dataclass(frozen=True)
class JointPosterior:
    """What one joint update gives: the posterior, and each measurement's NIS against
    the prior (in the order the measurements were given)."""

    mean: np.ndarray
    covariance: np.ndarray
    nis: tuple[float, ...]
    linearisation_error: float = 0.0
    """The update's largest linearisation error, in standard deviations of the measurement
    noise (module docstring); 0 where it was not computed."""
    symmetric: bool = False
    """Whether :attr:`covariance` is symmetric to the bit (this module's function mirrors
    its upper triangle; a numpy product is symmetric only to rounding)."""
    positive_definite: bool = False
    """Whether :attr:`covariance` is known finite and positive definite (this module's
    function factorises it, :func:`_cholesky_pivots_positive`); False: not checked."""


def _symmetric_product(left: ca.SX, right: ca.SX) -> ca.SX:
    """``left @ right.T`` for a product known to be symmetric: the upper triangle
    computed, the lower one its mirror (half the arithmetic: the lower triangle's products
    reach no output and are left out of the function; exactly symmetric)."""
    full = left @ right.T
    return ca.triu(full) + ca.triu(full, False).T


def _cholesky_pivots_positive(matrix: ca.SX) -> ca.SX:
    """1 where the symmetric ``matrix`` is finite and positive definite, else 0: every
    pivot of its Cholesky factorisation ``A = L L'`` positive and finite (the test LAPACK's
    ``potrf`` makes, which ``numpy.linalg.cholesky`` raises on), in the order of the
    unblocked algorithm (Golub and Van Loan, "Matrix Computations", 4th ed. 2013, alg.
    4.2.1), a column at a time: ``d_j = a_jj - sum_k<j l_jk^2``, ``l_jj = sqrt(d_j)``,
    ``l_ij = (a_ij - sum_k<j l_ik l_jk) / l_jj``. A non-finite entry makes some pivot NaN or
    infinite; a comparison with NaN is false."""
    n = matrix.shape[0]
    lower = ca.SX(n, n)
    positive = ca.SX(1.0)
    for j in range(n):
        row = lower[j, :j]
        pivot = matrix[j, j] - ca.sumsqr(row) if j else matrix[j, j]
        positive = positive * (pivot > 0.0) * (pivot < ca.inf)
        if j + 1 < n:
            column = matrix[j + 1:, j] - lower[j + 1:, :j] @ row.T if j else matrix[j + 1:, j]
            lower[j + 1:, j] = column / ca.sqrt(pivot)
    return positive


@built_once
def _joint_function(parts: tuple[tuple[ca.Function, int, tuple[int, ...]], ...],
                    belief_size: int) -> ca.Function:
    """``(x, x_l, P, z, r, mask, belief) -> (x+, P+, NIS per model, linearisation error,
    whether P+ is finite and positive definite)`` (module docstring) over the models
    ``parts`` (each: its ``h`` with Jacobian, its channel count, the rows of its angle
    channels), built once per process for the same model functions."""
    size = sum(count for _, count, _ in parts)
    n = len(STATE_NAMES)
    x = ca.SX.sym("x", n)
    at = ca.SX.sym("x_l", n)
    p = ca.SX.sym("P", n, n)
    z = ca.SX.sym("z", size)
    r = ca.SX.sym("r", size)
    mask = ca.SX.sym("mask", size)
    numbers = ca.SX.sym("belief", belief_size)
    values, jacobians, blocks = [], [], []
    angle_rows = set()
    start = 0
    for function, count, angles in parts:
        h, jacobian = function(at, numbers)
        values.append(h)
        jacobians.append(jacobian)
        blocks.append(range(start, start + count))
        angle_rows.update(start + row for row in angles)
        start += count
    stacked = ca.vertcat(*jacobians)
    residual = z - (ca.vertcat(*values) + stacked @ (x - at))
    innovation = ca.vertcat(*[
        wrap_angle_symbolic(residual[i]) if i in angle_rows else residual[i]
        for i in range(size)])
    innovation = mask * innovation
    observed = ca.diag(mask) @ stacked
    variance = mask * r + (1.0 - mask)
    noise = ca.diag(variance)
    pht = p @ observed.T
    s_matrix = observed @ pht + noise
    gain = ca.solve(s_matrix, pht.T).T
    i_kh = ca.SX.eye(n) - gain @ observed
    covariance = _symmetric_product(i_kh @ p, i_kh) + _symmetric_product(
        gain * ca.repmat((mask * r + (1.0 - mask)).T, n, 1), gain)
    symmetric_s = 0.5 * (s_matrix + s_matrix.T)
    nis = []
    for rows in blocks:
        index = list(rows)
        y_block = innovation[index]
        nis.append(ca.dot(y_block, ca.solve(symmetric_s[index, index], y_block)))
    posterior = x + gain @ innovation
    after = ca.vertcat(*[function(posterior, numbers)[0] for function, _, _ in parts])
    miss = after - ca.vertcat(*values) - stacked @ (posterior - at)
    miss = ca.vertcat(*[wrap_angle_symbolic(miss[i]) if i in angle_rows else miss[i]
                        for i in range(size)])
    error = ca.mmax(ca.fabs(mask * miss / ca.sqrt(variance)))
    return ca.Function(JOINT_FUNCTION, [x, at, p, z, r, mask, numbers],
                       [posterior, ca.densify(covariance), ca.vertcat(*nis), error,
                        _cholesky_pivots_positive(covariance)])


class JointUpdate:
    """The joint update over every channel of ``models`` (module docstring), built once.

    :meth:`__call__` places each measurement's channels at their rows of the stack and
    evaluates the function; :attr:`function` is the evaluator to compile.
    """

    def __init__(self, models: Mapping[str, MeasurementModel], belief: np.ndarray,
                 library: Path | None = None) -> None:
        """``library``, if given, holds the function compiled (an earlier process built it
        from the same models: :func:`estimation.compiled_models.recorded`): it is taken
        from there (``casadi.external``, the C the compiled call runs) instead of
        building its graph, some 20 ms of a new process's set-up."""
        self._offsets: dict[str, int] = {}
        offset = 0
        for sensor, model in models.items():
            self._offsets[sensor] = offset
            offset += len(model.channels)
        size = offset
        parts = tuple((model.function.function, len(model.channels),
                       tuple(model.channels.index(c) for c in model.angle_channels))
                      for model in models.values())
        function = _joint_function(parts, belief.size) if library is None else \
            external_function(JOINT_FUNCTION, library)
        self.function = DenseFunction(function, parameters=belief)
        """``(x, x_l, P, z, r, mask) -> (x+, P+, NIS per model, linearisation error)``, the
        belief set once."""
        self._order = tuple(models)
        self._layouts: dict[tuple[tuple[str, tuple[int, ...]], ...], _Layout | None] = {}
        self._z = np.zeros(size)

    def _layout(self, blocks: Sequence[tuple[MeasurementModel, Selection, np.ndarray]]
                ) -> _Layout | None:
        """Where the channels of ``blocks`` sit in the stack (found once per combination of
        sensors and channels); None when two blocks share a model."""
        key = tuple((model.sensor, selection.model_rows) for model, selection, _ in blocks)
        if key not in self._layouts:
            self._layouts[key] = self._new_layout(blocks)
        return self._layouts[key]

    def _new_layout(self, blocks: Sequence[tuple[MeasurementModel, Selection, np.ndarray]]
                    ) -> _Layout | None:
        seen: list[int] = []
        rows: list[int] = []
        for model, selection, _ in blocks:
            block = self._order.index(model.sensor)
            if block in seen:
                return None
            seen.append(block)
            rows += [self._offsets[model.sensor] + row for row in selection.model_rows]
        mask = np.zeros(self._z.size)
        mask[rows] = 1.0
        variance = np.ones(self._z.size)
        variance[rows] = np.concatenate([selection.model_variance for _, selection, _ in blocks])
        return _Layout(np.array(rows, dtype=int), mask, variance, np.array(seen, dtype=int))

    def __call__(self, mean: np.ndarray, covariance: np.ndarray,
                 blocks: Sequence[tuple[MeasurementModel, Selection, np.ndarray]],
                 linearise_at: np.ndarray | None = None) -> JointPosterior | None:
        """The joint update of ``blocks`` (model, selected channels, their values), one
        block per model, with the models linearised at ``linearise_at`` (None: the prior
        ``mean``); None when two blocks share a model or the result is not finite
        (a singular ``S``: the caller then fuses them one by one, which tells why)."""
        layout = self._layout(blocks)
        if layout is None:
            return None
        z = self._z
        z.fill(0.0)
        z[layout.rows] = np.concatenate([values for _, _, values in blocks])
        posterior, posterior_covariance, nis, error, positive = self.function(
            mean, mean if linearise_at is None else linearise_at, covariance, z,
            layout.variance, layout.mask)
        nis = nis.reshape(-1)[layout.blocks]
        if not (np.isfinite(posterior).all() and np.isfinite(nis).all()):
            return None
        return JointPosterior(posterior.reshape(-1), posterior_covariance,
                              tuple(nis.tolist()), float(error[0, 0]), symmetric=True,
                              positive_definite=positive[0, 0] == 1.0)


@dataclass(frozen=True)
class _Layout:
    """Where one combination of measurements sits in the stack of every channel."""

    rows: np.ndarray
    """The stack's rows of the measurements' channels, in their order."""
    mask: np.ndarray
    """1 on those rows, 0 elsewhere."""
    variance: np.ndarray
    """Their noise variances on those rows, 1 elsewhere."""
    blocks: np.ndarray
    """Each measurement's model, as its position among the models."""
