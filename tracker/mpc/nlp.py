"""An NLP built once and solved every control step: where the plan sits in its variables,
its bounds, and the solver's verdict.

:class:`Nlp` wraps a CasADi ``nlpsol`` (IPOPT, fatrop) or :class:`RealTimeIteration` (one
Gauss-Newton SQP step per control step, each a structured QP; Diehl, Bock, Schloeder,
Findeisen, Nagy, Allgoewer, "Real-time optimization and nonlinear model predictive control
of processes governed by differential-algebraic equations", J. Process Control 12(4),
2002) behind one :meth:`Nlp.solve`; :class:`StagedProblem` is the NLP posed stage by stage
before a solver is chosen (:mod:`tracker.mpc.nmpc_problem`).
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

if TYPE_CHECKING:
    from tracker.mpc.compiled_rti import CompiledRtiStep


@dataclass(frozen=True)
class Solution:
    """What one solve produced (before the tracker checks it is finite)."""

    w: np.ndarray
    cost: float
    status: str
    iterations: int
    success: bool
    solve_time_s: float


QP_FEASIBILITY_TOL = 1e-3
"""Largest violation of a bound or a linearised constraint a real-time iteration's step
may leave (in the variables' and constraints' own units)."""


OUT_OF_BOUNDS = "QP_Failed (step violates the bounds)"
"""The status of a real-time iteration whose QP's step fails :func:`step_feasible`."""


def step_feasible(w: np.ndarray, g_linear: np.ndarray, nlp: Nlp) -> bool:
    """Whether a QP's result honours the bounds and the linearised constraints: qrqp has
    reported success on an infeasible QP (with the friction ellipse's Hessian, an initial
    steering rate beyond its bound)."""
    tol = QP_FEASIBILITY_TOL
    return bool(np.all(w >= nlp.lbx - tol) and np.all(w <= nlp.ubx + tol)
                and np.all(g_linear >= nlp.lbg - tol) and np.all(g_linear <= nlp.ubg + tol))


@dataclass(frozen=True)
class RealTimeIteration:
    """Gauss-Newton SQP steps on the stage-wise NLP, each one structured QP (Diehl's
    real-time iteration), built once.

    ``qp_data(w, p) -> (H, grad f, g, J_g)``: the Gauss-Newton Hessian ``2 J_r' J_r`` of
    the cost's residuals, the cost gradient, the constraints and their Jacobian at the
    iterate ``w``; ``qp`` solves for the step ``dw``:
    ``min 1/2 dw' H dw + grad f' dw`` s.t. ``lbx <= w + dw <= ubx`` and
    ``lbg <= g + J_g dw <= ubg``; ``cost(w, p)`` is the NLP's cost at the result.

    ``compiled``, when given, is the whole step (these three functions and the QP solver)
    as C (:mod:`tracker.mpc.compiled_rti`): the same iterates, without CasADi's virtual
    machine or a conversion between numpy and CasADi matrices.

    CasADi's ``sqpmethod`` (``max_iter = 1``) does the same, but in CasADi 3.8 it carries
    on silently when a QP fails (``Maximum_Iterations_Exceeded`` either way) unless the QP
    raises, which dumps the whole QP to stdout; here every QP's status is checked.
    """

    qp_data: ca.Function
    qp: ca.Function
    cost: ca.Function
    iterations: int
    """Steps per control step from a warm start (``tracker.rti_iterations``)."""
    cold_iterations: int
    """Most steps from a cold guess (``tracker.max_iterations``)."""
    cold_tolerance: float
    """From a cold guess, the steps stop once the largest entry of a step is at most this
    (``tracker.tolerance``)."""
    compiled: CompiledRtiStep | None = None

    def solve(self, w: np.ndarray, params: np.ndarray, nlp: Nlp,
              cold: bool = False) -> Solution:
        """Full steps from ``w`` within ``nlp``'s bounds: ``iterations`` of them from a
        warm start; from a ``cold`` guess (no previous plan to shift) until a step is
        below ``cold_tolerance``, at most ``cold_iterations``: the iteration then starts
        the run at the NLP's solution, as a real-time iteration is meant to start (Diehl
        et al. 2002), instead of converging to it over the first second of the run; a
        cold start not converged within ``cold_iterations`` fails
        (``RTI_Not_Converged``), as fatrop and IPOPT fail at their limit. The first QP
        that fails ends it unsuccessfully (hpipm's status: 1 iteration limit, 2
        step too small, 3 NaN, 4 inconsistent equalities; qrqp and osqp report words; the
        compiled step says ``no solution``)."""
        start = time.perf_counter()
        limit = self.cold_iterations if cold else self.iterations
        cost: float | None = None
        converged = not cold
        for iteration in range(1, limit + 1):
            w_next, cost, status = self._step(w, params, nlp)
            if status:
                return Solution(w, math.nan, status, iteration, False,
                                time.perf_counter() - start)
            step_size = float(np.max(np.abs(w_next - w)))
            w = w_next
            if cold and step_size <= self.cold_tolerance:
                converged = True
                break
        if not converged:
            return Solution(w, math.nan, "RTI_Not_Converged", limit, False,
                            time.perf_counter() - start)
        if cost is None:
            cost = float(self.cost(w, params))
        return Solution(w, cost, "RTI_Completed", iteration, True, time.perf_counter() - start)

    def _step(self, w: np.ndarray, params: np.ndarray, nlp: Nlp
              ) -> tuple[np.ndarray, float | None, str]:
        """One full step: the next iterate, the cost there (when it comes for free) and
        the reason the step failed ("" when it did not)."""
        if self.compiled is not None:
            stepped = self.compiled(w, params)
            if stepped is None:
                return w, None, "QP_Failed (hpipm: no solution)"
            w_next, g_linear, cost = stepped
            if not step_feasible(w_next, g_linear, nlp):
                return w, None, OUT_OF_BOUNDS
            return w_next, cost, ""
        hessian, gradient, g, jacobian = self.qp_data(w, params)
        g = np.asarray(g, dtype=float).ravel()
        step = self.qp(h=hessian, g=gradient, a=jacobian, lbx=nlp.lbx - w,
                       ubx=nlp.ubx - w, lba=nlp.lbg - g, uba=nlp.ubg - g)
        stats = self.qp.stats()
        dw = np.asarray(step["x"], dtype=float).ravel()
        if not stats.get("success", False):
            return w, None, f"QP_Failed ({stats.get('return_status', 'unknown')})"
        if not step_feasible(w + dw, g + np.asarray(ca.mtimes(jacobian, dw)).ravel(), nlp):
            return w, None, OUT_OF_BOUNDS
        return w + dw, None, ""


@dataclass(frozen=True)
class Nlp:
    """One solver's NLP, built once: the solver, where the plan sits in its flat vector of
    variables ``w``, and the bounds (the parameters vary, nothing else does)."""

    solver_name: str
    """``tracker.solver``."""
    solver: ca.Function | RealTimeIteration
    """A CasADi ``nlpsol`` (ipopt, fatrop), or the real-time iteration (sqp-rti)."""
    state_index: np.ndarray
    """``(N+1, n_x)`` integers: ``w[state_index[k, i]]`` is state ``i`` at node ``k``."""
    input_index: np.ndarray
    """``(N, n_u)`` integers: ``w[input_index[k, j]]`` is input ``j`` of stage ``k``."""
    carried_index: np.ndarray
    """``(N+1, n_u)`` integers: the input applied before node ``k``, which the stage-wise
    NLPs carry as a state (row 0: the previously applied command); ``(0, n_u)`` when the
    NLP has none."""
    lbx: np.ndarray
    ubx: np.ndarray
    lbg: np.ndarray
    ubg: np.ndarray

    def pack(self, states: np.ndarray, inputs: np.ndarray,
             input_prev: np.ndarray) -> np.ndarray:
        """The flat vector of variables holding a trajectory (e.g. a warm start)."""
        w = np.empty(self.lbx.size)
        w[self.state_index] = states
        w[self.input_index] = inputs
        if self.carried_index.size:
            w[self.carried_index] = np.vstack((input_prev, inputs))
        return w

    def solve(self, w0: np.ndarray, params: np.ndarray, cold: bool = False) -> Solution:
        """Solve from the guess ``w0`` (``cold``: not a previous plan shifted, which the
        real-time iteration takes to convergence); CasADi errors raise ``RuntimeError``.

        Success is each solver's own verdict: IPOPT's and fatrop's ``success`` (converged
        to ``tracker.tolerance``), the real-time iteration's every QP solved. The status
        is IPOPT's ``return_status``; fatrop's is an integer flag, reported as
        ``Solve_Succeeded`` (0) or ``fatrop_flag_<n>`` (1 both at the iteration limit and
        on an infeasible problem); the real-time iteration's ``RTI_Completed`` or
        ``QP_Failed (<the QP solver's status>)``.
        """
        if isinstance(self.solver, RealTimeIteration):
            return self.solver.solve(w0, params, self, cold)
        call = self._call
        start = time.perf_counter()
        w, cost = call(w0, params)
        solve_time_s = time.perf_counter() - start
        stats = call.stats()
        success = bool(stats.get("success", False))
        status = str(stats.get("return_status", "unknown"))
        if self.solver_name == "fatrop":
            status = "Solve_Succeeded" if success else f"fatrop_flag_{status}"
        return Solution(w, cost, status, int(stats.get("iter_count", 0)), success,
                        solve_time_s)

    @functools.cached_property
    def _call(self) -> BufferedNlpCall:
        """The solver called on numpy arrays bound once (:class:`BufferedNlpCall`)."""
        assert isinstance(self.solver, ca.Function)
        return BufferedNlpCall(self.solver, {"lbx": self.lbx, "ubx": self.ubx,
                                             "lbg": self.lbg, "ubg": self.ubg})


class BufferedNlpCall:
    """A CasADi ``nlpsol`` (or a ``qpsol``, which takes and gives the same) evaluated
    through its buffer (``Function.buffer``): every input and output is a numpy array bound
    to the solver once, so a solve converts nothing (called with a dict, each solve turned
    the guess, the parameters and the bounds into CasADi matrices and every output back,
    some 100 us). The same solver, so the same iterates. Inputs not set here (the
    multipliers' initial guesses) stay zero, as in a call that does not give them."""

    def __init__(self, solver: ca.Function, fixed: Mapping[str, np.ndarray]) -> None:
        self._inputs = {name: np.zeros(solver.nnz_in(i))
                        for i, name in enumerate(solver.name_in())}
        self._outputs = {name: np.zeros(solver.nnz_out(i))
                         for i, name in enumerate(solver.name_out())}
        for name, values in fixed.items():
            self._inputs[name][:] = np.asarray(values, dtype=float).ravel()
        self._buffer, self._evaluate = solver.buffer()
        for i, name in enumerate(solver.name_in()):
            self._buffer.set_arg(i, memoryview(self._inputs[name]))
        for i, name in enumerate(solver.name_out()):
            self._buffer.set_res(i, memoryview(self._outputs[name]))

    def __call__(self, w0: np.ndarray | float, params: np.ndarray,
                 **bounds: np.ndarray) -> tuple[np.ndarray, float]:
        """Solve from the guess ``w0`` with the parameters ``params`` (and, for a problem
        whose bounds move, this solve's ``lbx``, ``ubx``, ``lbg`` or ``ubg``; the others
        stay as they were): the solution and its cost; a solver that reports an error (not
        a failed solve: an evaluation that could not run) raises ``RuntimeError``, as a call
        with a dict does."""
        self._inputs["x0"][:] = w0
        self._inputs["p"][:] = params
        for name, values in bounds.items():
            self._inputs[name][:] = values
        self._evaluate()
        if self._buffer.ret():
            raise RuntimeError(f"the NLP solver returned {self._buffer.ret()}")
        return self._outputs["x"].copy(), float(self._outputs["f"][0])

    def stats(self) -> dict[str, object]:
        """The solver's statistics of the last solve (``success``, ``return_status``,
        ``iter_count`` ...): the buffer has its own memory, so the solver's ``stats()``
        does not hold them."""
        return self._buffer.stats()


@dataclass(frozen=True)
class StagedProblem:
    """The NLP posed stage by stage
    (:meth:`tracker.mpc.nmpc_problem.NmpcProblem.staged_problem`), before a solver."""

    nlp: Mapping[str, ca.SX]
    """CasADi's NLP: variables ``x``, parameters ``p``, cost ``f``, constraints ``g``."""
    residuals: ca.SX
    """``r`` with ``f = |r|^2``: the weighted errors, for a Gauss-Newton Hessian."""
    structure: Mapping[str, object]
    """The stages' sizes as fatrop and hpipm take them: ``N``, ``nx``, ``nu``, ``ng``."""
    layout: Mapping[str, np.ndarray]
    """The :class:`Nlp` fields other than the solver: indices and bounds."""

    def with_solver(self, solver_name: str,
                    solver: ca.Function | RealTimeIteration) -> Nlp:
        return Nlp(solver_name, solver, **self.layout)
