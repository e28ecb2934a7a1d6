"""The quadratic programme of one LTV-MPC step, built once.

**Linearisation.** As Falcone et al. (IEEE TCST 2007, sec. IV), Taylor-linearise the model about a
trajectory ``(xbar_k, ubar_k)``, subtracts it, and obtains a linear time-varying model of the
deviations ``x~ = x - xbar``, ``u~ = u - ubar``. Here the model is the discrete stage map
``F`` itself (RK4, :func:`tracker.models.steered_dynamic_bicycle.discrete_function`), so nothing
is lost to a second discretisation::

    x~_{k+1} = A_k x~_k + B_k u~_k + c_k                                     (L1)
    A_k = dF/dx (xbar_k, ubar_k),  B_k = dF/du (xbar_k, ubar_k)              (L2)
    c_k = F(xbar_k, ubar_k) - xbar_{k+1}                                     (L3)

``c_k`` is the defect of the linearisation trajectory: zero for a trajectory of the model,
non-zero for a reference that is not one (Lages and Alves, IFAC 2006, linearise about the
reference ``(X_r, U_r)``, which the car's model does not follow exactly). Limits ``h(x)`` (the
tyres' slip angles) are linearised the same way at nodes 1..N::

    h(x_k) ~ h(xbar_k) + H_k x~_k,   H_k = dh/dx (xbar_k)                    (L5)

:class:`Linearisation` evaluates (L2), (L3) and (L5) at every stage in one call of one
CasADi Function (exact Jacobians by ``ca.jacobian``, mapped over the horizon), built once.

**Rates.** The cost penalises input rates and the steering rate is bounded, both against
the previous input; to keep every constraint and cost term within one stage (the form an
OCP solver such as HPIPM needs) the state is augmented with the previous input (the
``Delta u`` form of :mod:`tracker.mpc.dynamic_mpc` does the same; L. Wang, Springer 2009)::

    z_k = [x_k; u_{k-1}],   z_{k+1} = [F(x_k, u_k); u_k],   u_{-1} = applied input   (L4)

so a deviation ``z~`` obeys (L1) with ``[[A_k, 0], [0, 0]]``, ``[B_k; I]`` and ``[c_k; 0]``.
``z~_0`` is known (the initial state less ``xbar_0``, and ``ubar_{-1}`` is the applied
input), so it is a parameter, not a variable.

**The QP** (``tracker.ltv_mpc.formulation``):

* ``sparse`` (multiple shooting): variables stage by stage,
  ``[u~_0, z~_1, u~_1, s_1, ..., z~_N]``, constraints
  ``[gap_0, rate_0, gap_1, rate_1, limits_1, ...]`` with
  ``gap_k = [A_k x~_k + B_k u~_k; u~_k] - z~_{k+1} = -[c_k; 0]``: the block-banded form
  HPIPM's Riccati recursion solves in ``O(N)``. Node N has no inputs in that form
  (CasADi's HPIPM interface gives the last stage none), so its limit and slack belong to
  stage N-1, written through (L1) from stage N-1.
* ``condensed``: (L1) eliminates the states, ``z~_k`` becomes an affine expression in
  ``u~_0 .. u~_{k-1}`` (and ``c``, a parameter); variables ``[u~, s]`` only, a small dense
  QP for the active-set solvers and OSQP.

``rate_k = delta~_k - delta~_{k-1}`` is bounded by ``max_steer_rate_radps dt`` less the
trajectory's own rate. ``limits_k`` are the soft limits at nodes 1..N, one two-sided row
per limit with a free slack ``s_k`` (no bound of its own)::

    -h_max <= h(xbar_k) + H_k x~_k + s_k <= h_max                             (L6)

The cost is :mod:`tracker.config`'s, written in the absolute quantities ``x = xbar + x~``,
``u = ubar + u~``: cross-track error against each reference point's tangent, heading and
speed error at nodes 1..N; acceleration, steering and their rates at stages 0..N-1; and
``dt weights.limit_excess s_k^2``, which at the optimum (``|s_k| = max(|h| - h_max, 0)``)
is the NMPC's exterior penalty exactly. Every term is the square of an affine function of
the variables, so the cost is exactly quadratic: the QP is :mod:`tracker.mpc.nmpc`'s NLP with
(L1) and (L5) for the model and its limits. (Two one-sided rows with ``s >= 0`` are the
same QP; they took HPIPM 10 iterations instead of 4.)

Everything that changes from step to step (``A_k``, ``B_k``, ``H_k``, the linearisation
trajectory, the reference, the previous input) is a parameter ``p`` of one
``ca.qpsol(name, plugin, {"x", "p", "f", "g"}, options)`` built in the constructor, or a
bound passed at the call (``c_k``, ``h(xbar_k)``, the input bounds less ``ubar``): a step
never rebuilds the solver.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

import casadi as ca
import numpy as np

from cosim.core.dense_function import DenseFunction, densified
from cosim.core.exceptions import ConfigError
from tracker.config import TrackerConfig
from tracker.mpc.fallback import INPUT, INPUT_NAMES
from tracker.mpc.ltv_mpc_config import QP_SOLVERS
from tracker.mpc.nlp import BufferedNlpCall
from tracker.mpc.tracking_cost import input_terms, tracking_terms, weighted_squares
from tracker.mpc.vector_layout import VectorLayout

TRACKING_STATE_NAMES: tuple[str, ...] = ("x_m", "y_m", "yaw_rad", "vx_mps")
"""States the tracking cost reads: CoG position (world frame), yaw, forward speed."""

REFERENCE_NAMES: tuple[str, ...] = ("ref_x_m", "ref_y_m", "ref_yaw_rad", "ref_speed_mps")
"""The reference at nodes 1..N, one value per node: position, path yaw, speed."""

_HPIPM_STATUS: Mapping[str, str] = MappingProxyType({
    "0": "SUCCESS", "1": "MAX_ITER", "2": "MIN_STEP", "3": "NAN_SOL", "4": "INCONS_EQ",
})
"""HPIPM's ``hpipm_status`` codes by name (CasADi reports the number)."""


# ---------------------------------------------------------------------- linearisation


@dataclass(frozen=True)
class StageLinearisation:
    """(L2), (L3) and (L5) along the horizon, one row per stage ``k = 0 .. N-1``.

    ``a_nonzeros`` (N, nnz(A)) and ``b_nonzeros`` (N, nnz(B)) are the structural nonzeros
    of ``A_k``, ``B_k`` in CasADi's column-major order (:attr:`Linearisation.a_sparsity`,
    :attr:`Linearisation.b_sparsity`); ``defects`` (N, n_x) are ``c_k``;
    ``limit_values`` (N, n_h) and ``limit_jacobian_nonzeros`` (N, nnz(H)) are ``h`` and
    ``H`` at node ``k + 1`` (empty without limits).
    """

    a_nonzeros: np.ndarray
    b_nonzeros: np.ndarray
    defects: np.ndarray
    limit_values: np.ndarray
    limit_jacobian_nonzeros: np.ndarray


class Linearisation:
    """(L2), (L3) and (L5) of a stage map along a horizon, in one call.

    Args:
      step: ``F(state, inputs) -> next_state`` over one stage (a CasADi Function).
      horizon: the number of stages N.
      limits: ``h(state) -> limited quantities`` (a CasADi Function), or None.
    """

    def __init__(self, step: ca.Function, horizon: int, limits: ca.Function | None = None
                 ) -> None:
        if step.n_in() != 2 or step.n_out() != 1:
            raise ConfigError(f"step {step.name()}: expected F(state, inputs) -> next_state")
        if not (isinstance(horizon, int) and horizon >= 1):
            raise ConfigError(f"horizon = {horizon!r}: expected an integer >= 1")
        self.n_x = step.size1_in(0)
        self.n_u = step.size1_in(1)
        if limits is not None and (limits.n_in() != 1 or limits.size1_in(0) != self.n_x):
            raise ConfigError(f"limits {limits.name()}: expected h(state) of {self.n_x} states")
        self.horizon = horizon
        state = ca.SX.sym("state", self.n_x)
        inputs = ca.SX.sym("inputs", self.n_u)
        next_bar = ca.SX.sym("next_state_bar", self.n_x)
        next_state = step(state, inputs)
        a = ca.jacobian(next_state, state)  # (L2)
        b = ca.jacobian(next_state, inputs)
        h = limits(next_bar) if limits is not None else ca.SX(0, 1)
        h_jacobian = ca.jacobian(h, next_bar)  # (L5)
        self.a_sparsity: ca.Sparsity = a.sparsity()
        self.b_sparsity: ca.Sparsity = b.sparsity()
        self.limit_sparsity: ca.Sparsity = h_jacobian.sparsity()
        self.n_limits = h.size1()
        stage = ca.Function(
            "ltv_stage", [state, inputs, next_bar],
            [ca.vertcat(*a.nonzeros()), ca.vertcat(*b.nonzeros()),
             next_state - next_bar,  # (L3)
             h, ca.vertcat(*h_jacobian.nonzeros())],
            ["state", "inputs", "next_state_bar"],
            ["a_nonzeros", "b_nonzeros", "defect", "limits", "limit_jacobian_nonzeros"],
        )
        self._along_horizon = DenseFunction(densified(stage.map(horizon)))  # buffers bound once

    def __call__(self, states: np.ndarray, inputs: np.ndarray) -> StageLinearisation:
        """Along ``states`` (N+1, n_x) and ``inputs`` (N, n_u)."""
        if states.shape != (self.horizon + 1, self.n_x) or inputs.shape != (self.horizon,
                                                                             self.n_u):
            raise ValueError(f"states {states.shape}, inputs {inputs.shape}: expected "
                             f"({self.horizon + 1}, {self.n_x}), ({self.horizon}, {self.n_u})")
        out = self._along_horizon(states[:-1].T, inputs.T, states[1:].T)
        a_nz, b_nz, defects, h, h_jacobian = (np.asarray(o, dtype=float).T for o in out)
        return StageLinearisation(a_nz.reshape(self.horizon, -1), b_nz.reshape(self.horizon, -1),
                                  defects.reshape(self.horizon, -1), h.reshape(self.horizon, -1),
                                  h_jacobian.reshape(self.horizon, -1))

    def matrices(self, linearisation: StageLinearisation, k: int
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Dense ``(A_k, B_k, H_{k+1})`` of stage ``k``, for checks and tests."""
        def dense(sparsity: ca.Sparsity, nonzeros: np.ndarray) -> np.ndarray:
            return np.asarray(ca.densify(ca.DM(sparsity, nonzeros)), dtype=float)

        return (dense(self.a_sparsity, linearisation.a_nonzeros[k]),
                dense(self.b_sparsity, linearisation.b_nonzeros[k]),
                dense(self.limit_sparsity, linearisation.limit_jacobian_nonzeros[k]))


# ---------------------------------------------------------------------- the QP


@dataclass(frozen=True)
class QpProblem:
    """The numbers of one step's QP.

    Shapes: ``state_bar`` (N+1, n_x) and ``input_bar`` (N, n_u) are the linearisation
    trajectory; ``linearisation`` is (L2), (L3), (L5) along it; ``state0`` (n_x,) is the
    initial state; ``input_prev`` (n_u,) the input applied before the first stage;
    ``reference`` maps each of :data:`REFERENCE_NAMES` to N values (nodes 1..N).
    """

    state_bar: np.ndarray
    input_bar: np.ndarray
    linearisation: StageLinearisation
    state0: np.ndarray
    input_prev: np.ndarray
    reference: Mapping[str, np.ndarray]
    steer_rate_weight: float
    """This step's ``weights.steer_rate`` (the caution's, :mod:`tracker.mpc.caution`): a
    parameter of the QP, the other weights are its numbers."""


@dataclass(frozen=True)
class QpResult:
    """What one QP solve gave: the absolute trajectory and the back-end's report.

    ``states`` (N+1, n_x) and ``inputs`` (N, n_u) are ``xbar + x~`` (node 0: the initial
    state) and ``ubar + u~``, unclipped; ``cost`` is the LTV cost with its constant terms;
    ``solve_time_s`` is the wall time of the back-end's call alone; ``iterations`` the
    back-end's count (at least 1 for a solved QP: OSQP's count is not exposed through
    CasADi, and qpOASES counts working-set changes, 0 when no bound becomes active).
    """

    states: np.ndarray
    inputs: np.ndarray
    cost: float
    solve_time_s: float
    iterations: int
    status: str
    success: bool


class _Stack:
    """Symbolic blocks stacked into one vector, remembering where each named block went."""

    def __init__(self) -> None:
        self._parts: list[ca.SX] = []
        self._index: dict[str, list[np.ndarray]] = {}
        self.size = 0

    def add(self, name: str, block: ca.SX) -> None:
        rows = np.arange(self.size, self.size + block.size1())
        self._index.setdefault(name, []).append(rows)
        self._parts.append(block)
        self.size += block.size1()

    def rows(self, name: str) -> np.ndarray:
        """Indices of every block named ``name``, one row per block (empty if none)."""
        blocks = self._index.get(name, [])
        return np.array(blocks, dtype=int) if blocks else np.zeros((0, 0), dtype=int)

    def stacked(self) -> ca.SX:
        return ca.vertcat(*self._parts)


@dataclass(frozen=True)
class _Stages:
    """The QP's symbols and expressions, stage by stage, before they are stacked."""

    p: ca.SX
    """The parameters (:attr:`LtvQp._params`)."""
    z: list[ca.SX]
    """``z~_k = [x~_k, u~_{k-1}]`` per node (node 0 known; condensed: predicted)."""
    u: list[ca.SX]
    """The input deviations per stage."""
    slack: list[ca.SX]
    """The soft limits' slacks per node (node 0's unused)."""
    gaps: list[ca.SX]
    """(L1) and (L4) as equality rows (multiple shooting only)."""
    rates: list[ca.SX]
    """The steering-rate rows."""
    limits: list[ca.SX]
    """``H_k x~_k`` of (L5) per node (node 0 empty)."""
    cost: ca.SX


def _solver_options(plugin: str, config: TrackerConfig) -> dict[str, Any]:
    """Each back-end's options: quiet, no exception on failure, ``qp_tolerance`` and
    ``qp_max_iterations`` in its own terms.

    HPIPM runs in its ``speed_abs`` mode (absolute residuals, no iterative refinement):
    on this QP it takes 3 iterations where ``robust`` takes 9 and stalls at tolerances
    below 1e-6.
    """
    ltv = config.ltv_mpc
    tol, max_iter = ltv.qp_tolerance, ltv.qp_max_iterations
    common: dict[str, Any] = {"error_on_fail": False, "print_time": False}
    if plugin == "hpipm":
        return common | {"hpipm": {"mode": "speed_abs", "iter_max": max_iter,
                                   "res_g_max": tol, "res_b_max": tol, "res_d_max": tol,
                                   "res_m_max": tol}}
    if plugin == "osqp":
        return common | {"warm_start_primal": True, "warm_start_dual": False,
                         "osqp": {"verbose": False, "eps_abs": tol, "eps_rel": tol,
                                  "max_iter": max_iter, "polish": False}}
    if plugin == "qrqp":
        return common | {"max_iter": max_iter, "print_iter": False, "print_header": False,
                         "print_info": False, "constr_viol_tol": tol, "dual_inf_tol": tol}
    if plugin == "qpoases":
        return common | {"printLevel": "none", "nWSR": max_iter, "sparse": False,
                         "terminationTolerance": tol}
    raise ConfigError(f"tracker.ltv_mpc.qp_solver = {plugin!r}: expected one of "
                      f"{', '.join(QP_SOLVERS)}")


class LtvQp:
    """The QP of one LTV-MPC step, built once (see the module docstring).

    Args:
      config: horizon, stage length, cost weights, input bounds, and ``config.ltv_mpc``'s
        back-end, formulation, iteration limit and tolerance.
      state_names: the model's states, in vector order (must include
        :data:`TRACKING_STATE_NAMES`).
      linearisation: (L2), (L3), (L5) of the model over ``config.horizon`` stages.
      limit_bounds: ``h_max`` for each of the linearisation's limits (soft,
        ``weights.limit_excess``).
    """

    def __init__(self, config: TrackerConfig, state_names: tuple[str, ...],
                 linearisation: Linearisation, limit_bounds: tuple[float, ...] = ()) -> None:
        missing = [name for name in TRACKING_STATE_NAMES if name not in state_names]
        if missing:
            raise ConfigError(f"LTV-MPC model: expected states {missing}")
        if linearisation.horizon != config.horizon:
            raise ConfigError(f"linearisation horizon {linearisation.horizon}: expected "
                              f"tracker.horizon = {config.horizon}")
        if (linearisation.n_x, linearisation.n_u) != (len(state_names), len(INPUT_NAMES)):
            raise ConfigError(f"linearisation of {linearisation.n_x} states and "
                              f"{linearisation.n_u} inputs: expected {len(state_names)} and "
                              f"{len(INPUT_NAMES)}")
        if len(limit_bounds) != linearisation.n_limits or not all(
                math.isfinite(b) and b > 0.0 for b in limit_bounds):
            raise ConfigError(f"limit_bounds = {limit_bounds}: expected "
                              f"{linearisation.n_limits} positive numbers")
        self.config = config
        self.plugin = config.ltv_mpc.qp_solver
        self.condensed = config.ltv_mpc.qp_formulation == "condensed"
        self._state = MappingProxyType({name: i for i, name in enumerate(state_names)})
        self._lin = linearisation
        self._limit_bounds = np.array(limit_bounds, dtype=float)
        n, n_x, n_u = config.horizon, len(state_names), len(INPUT_NAMES)
        self._n, self._n_x, self._n_u = n, n_x, n_u
        self._n_z = n_x + n_u
        self._params = VectorLayout((
            ("a_nonzeros", linearisation.a_sparsity.nnz() * n),
            ("b_nonzeros", linearisation.b_sparsity.nnz() * n),
            ("limit_jacobian_nonzeros", linearisation.limit_sparsity.nnz() * n),
            ("defects", n_x * n),
            ("state_bar", n_x * (n + 1)),
            ("input_bar", n_u * n),
            ("input_prev", n_u),
            ("state0_dev", n_x),
            *((name, n) for name in REFERENCE_NAMES),
            ("steer_rate_weight", 1),
        ))
        low, high = np.empty(n_u), np.empty(n_u)
        low[INPUT["accel_mps2"]], high[INPUT["accel_mps2"]] = (config.accel_min_mps2,
                                                               config.accel_max_mps2)
        low[INPUT["steer_rad"]], high[INPUT["steer_rad"]] = (-config.max_steer_rad,
                                                             config.max_steer_rad)
        self.input_low, self.input_high = low, high
        """Bounds of the inputs, in :data:`tracker.mpc.fallback.INPUT_NAMES` order."""
        self._rate_step = config.max_steer_rate_radps * config.dt_s
        self._build()

    # ------------------------------------------------------------------ construction

    def _build(self) -> None:
        """The QP of every step, built once with the step's numbers as parameters."""
        stages = self._stages()
        x, g, stage_nu, stage_ng = self._stack(stages)
        cfg, n, n_x, n_u = self.config, self._n, self._n_x, self._n_u
        options = _solver_options(self.plugin, cfg)
        if self.plugin == "hpipm":
            options |= {"N": n, "nx": [0] + [n_x + n_u] * n, "nu": stage_nu, "ng": stage_ng}
        p, cost = stages.p, stages.cost
        solver = ca.qpsol("ltv_mpc_qp", self.plugin, {"x": x, "p": p, "f": cost, "g": g},
                          options)
        self._call = BufferedNlpCall(solver, {})  # numpy arrays bound once
        # Evaluated on buffers bound once (cosim.core.dense_function): the same numbers.
        self._cost = DenseFunction(densified(ca.Function("ltv_mpc_cost", [x, p], [cost])))
        self._deviations = DenseFunction(densified(ca.Function(
            "ltv_mpc_deviations", [x, p], [ca.horzcat(*stages.z[1:])[:n_x, :].T])))

    def _stages(self) -> _Stages:
        """Each stage's deviation variables, (L1) and (L4), the steering rate, the cost at
        absolute values and the soft limits (L5), stage by stage."""
        cfg = self.config
        n, n_x, n_u, n_h, dt = self._n, self._n_x, self._n_u, self._lin.n_limits, cfg.dt_s
        index = self._state
        steer = INPUT["steer_rad"]
        p = ca.SX.sym("p", self._params.size)
        par = {name: p[s] for name, s in self._params.slices.items()}
        w = dataclasses.replace(cfg.weights, steer_rate=par["steer_rate_weight"])
        a_nnz, b_nnz = self._lin.a_sparsity.nnz(), self._lin.b_sparsity.nnz()
        h_nnz = self._lin.limit_sparsity.nnz()
        state_bar = ca.reshape(par["state_bar"], n_x, n + 1)
        input_bar = ca.reshape(par["input_bar"], n_u, n)

        u = [ca.SX.sym(f"u{k}", n_u) for k in range(n)]
        slack = [ca.SX.sym(f"s{k}", n_h) for k in range(n + 1)]  # s_0 unused
        z = [ca.vertcat(par["state0_dev"], ca.SX.zeros(n_u))]  # z~_0, known
        gaps, rates, limits = [], [], [ca.SX(0, 1)]
        cost = 0
        for k in range(n):
            a = ca.SX(self._lin.a_sparsity, par["a_nonzeros"][k * a_nnz:(k + 1) * a_nnz])
            b = ca.SX(self._lin.b_sparsity, par["b_nonzeros"][k * b_nnz:(k + 1) * b_nnz])
            x_dev, u_prev_dev = z[k][:n_x], z[k][n_x:]
            step = ca.vertcat(ca.mtimes(a, x_dev) + ca.mtimes(b, u[k]), u[k])  # (L1), (L4)
            predicted = step + ca.vertcat(par["defects"][k * n_x:(k + 1) * n_x],
                                          ca.SX.zeros(n_u))
            if self.condensed:
                z.append(predicted)
            else:
                z.append(ca.SX.sym(f"z{k + 1}", n_x + n_u))
                gaps.append(step - z[k + 1])
            rates.append(u[k][steer] - u_prev_dev[steer])

            # Stage cost at absolute values (tracker.config): inputs and input rates.
            previous_bar = par["input_prev"] if k == 0 else input_bar[:, k - 1]
            u_abs = input_bar[:, k] + u[k]
            u_prev_abs = previous_bar + u_prev_dev
            cost += dt * weighted_squares(input_terms(u_abs, u_prev_abs, dt, w))

            # Tracking at node k + 1 against reference point k (nodes 1..N).
            x_abs = state_bar[:, k + 1] + z[k + 1][:n_x]
            cost += dt * weighted_squares(tracking_terms(
                x_abs, index, par["ref_x_m"][k], par["ref_y_m"][k], par["ref_yaw_rad"][k],
                par["ref_speed_mps"][k], w))

            # Soft limits at node k + 1, (L5): |h + H x~| <= h_max + s, s >= 0.
            h_jacobian = ca.SX(self._lin.limit_sparsity,
                               par["limit_jacobian_nonzeros"][k * h_nnz:(k + 1) * h_nnz])
            # The last node has no inputs in HPIPM's stage form (CasADi's interface gives it
            # none), so its limit is imposed through the last stage's prediction, exact
            # under (L1); the other nodes' through their own state.
            last = k == n - 1 and not self.condensed
            node = predicted if last else z[k + 1]
            limits.append(ca.mtimes(h_jacobian, node[:n_x]))
            cost += dt * w.limit_excess * ca.sumsqr(slack[k + 1])
        return _Stages(p, z, u, slack, gaps, rates, limits, cost)

    def _stack(self, stages: _Stages) -> tuple[ca.SX, ca.SX, list[int], list[int]]:
        """Variables and constraints stacked stage by stage (HPIPM's order: stage k's state,
        its inputs, then the gap to stage k + 1 and stage k's own constraints; node N's
        limit and slack belong to stage N - 1), or inputs then slacks if condensed; with
        each stage's number of inputs and constraints. Remembers where each block went."""
        n, n_u, n_h = self._n, self._n_u, self._lin.n_limits
        z, u, slack = stages.z, stages.u, stages.slack
        variables, constraints = _Stack(), _Stack()
        stage_nu, stage_ng = [0] * (n + 1), [0] * (n + 1)
        for k in range(n):
            limited_nodes = [node for node in (k, k + 1)
                             if n_h and node >= 1 and (node == k or node == n)]
            if k >= 1 and not self.condensed:
                variables.add("states", z[k])
            variables.add("inputs", u[k])
            stage_nu[k] += n_u
            if not self.condensed:
                for node in limited_nodes:
                    variables.add("slack", slack[node])
                    stage_nu[k] += n_h
                constraints.add("gap", stages.gaps[k])
            constraints.add("rate", stages.rates[k])
            stage_ng[k] += 1
            for node in limited_nodes:
                constraints.add("limit", stages.limits[node] + slack[node])
                stage_ng[k] += n_h
        if not self.condensed:
            variables.add("states", z[n])
        elif n_h:
            for node in range(1, n + 1):
                variables.add("slack", slack[node])
        x, g = variables.stacked(), constraints.stacked()
        self._input_index = variables.rows("inputs")
        self._slack_index = variables.rows("slack")
        self._gap_index = constraints.rows("gap")
        self._rate_index = constraints.rows("rate").ravel()
        self._limit_index = constraints.rows("limit")
        self._n_variables, self._n_constraints = x.size1(), g.size1()
        return x, g, stage_nu, stage_ng

    # ------------------------------------------------------------------ solve

    def solve(self, problem: QpProblem) -> QpResult:
        """Solve one step's QP; a back-end failure is ``success=False``, never raised."""
        n, n_u = self._n, self._n_u
        steer = INPUT["steer_rad"]
        lin = problem.linearisation
        params = self._params.pack({
            "a_nonzeros": lin.a_nonzeros, "b_nonzeros": lin.b_nonzeros,
            "limit_jacobian_nonzeros": lin.limit_jacobian_nonzeros,
            "defects": lin.defects,
            "state_bar": problem.state_bar, "input_bar": problem.input_bar,
            "input_prev": problem.input_prev,
            "state0_dev": problem.state0 - problem.state_bar[0],
            **{name: problem.reference[name] for name in REFERENCE_NAMES},
            "steer_rate_weight": problem.steer_rate_weight,
        })
        lbx = np.full(self._n_variables, -np.inf)
        ubx = np.full(self._n_variables, np.inf)
        lbx[self._input_index] = self.input_low - problem.input_bar
        ubx[self._input_index] = self.input_high - problem.input_bar

        lbg = np.full(self._n_constraints, -np.inf)
        ubg = np.full(self._n_constraints, np.inf)
        if not self.condensed:
            gaps = np.concatenate((-lin.defects, np.zeros((n, n_u))), axis=1)  # (L3)
            lbg[self._gap_index] = gaps
            ubg[self._gap_index] = gaps
        previous = np.concatenate(([problem.input_prev[steer]], problem.input_bar[:-1, steer]))
        bar_rate = problem.input_bar[:, steer] - previous
        lbg[self._rate_index] = -self._rate_step - bar_rate
        ubg[self._rate_index] = self._rate_step - bar_rate
        if self._lin.n_limits:
            ubg[self._limit_index] = self._limit_bounds - lin.limit_values
            lbg[self._limit_index] = -self._limit_bounds - lin.limit_values

        start = time.perf_counter()
        try:
            solution_x, _ = self._call(0.0, params, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
            stats = self._call.stats()
        except RuntimeError as error:  # CasADi evaluation errors: a failed solve.
            return self._failed(f"error: {error}", time.perf_counter() - start)
        solve_time_s = time.perf_counter() - start

        if not np.all(np.isfinite(solution_x)):
            return self._failed("non-finite solution", solve_time_s)
        states = problem.state_bar.copy()
        states[0] = problem.state0
        states[1:] += self._deviations(solution_x, params)[0]
        inputs = problem.input_bar + solution_x[self._input_index]
        cost = float(self._cost(solution_x, params)[0][0, 0])
        status = str(stats.get("return_status", "unknown"))
        if self.plugin == "hpipm":
            status = _HPIPM_STATUS.get(status, f"HPIPM status {status}")
        success = bool(stats.get("success", False)) and math.isfinite(cost)
        iterations = int(stats.get("iter_count", 0))
        iterations = max(iterations, 1) if success else max(iterations, 0)
        return QpResult(states, inputs, cost, solve_time_s, iterations, status, success)

    def _failed(self, status: str, solve_time_s: float) -> QpResult:
        return QpResult(np.full((self._n + 1, self._n_x), np.nan),
                        np.full((self._n, self._n_u), np.nan), math.nan, solve_time_s, 0,
                        status, False)
