"""The NLP machinery every nonlinear MPC path tracker shares.

Tracking MPC by multiple shooting as in Rawlings, Mayne, Diehl, "Model Predictive Control:
Theory, Computation, and Design", 2nd ed., Nob Hill 2017; on a kinematic bicycle as in
Kong, Pfeiffer, Schildbach, Borrelli, "Kinematic and dynamic vehicle models for autonomous
driving control design", IEEE Intelligent Vehicles Symposium 2015.

At every control step solve, by multiple shooting with the NLP solver ``tracker.solver``,
``min_{x,u} sum_k c_k(x_k, u_k)  s.t.  x_{k+1} = F(x_k, u_k), x_0 = estimated state``,
apply the first input and keep the rest as the next warm start. A tracker is an
:class:`NmpcModel` (the model ``F`` and how its state is formed from an estimate) plus a
:class:`tracker.config.TrackerConfig`; :class:`Nmpc` does the rest:

* Reference: the estimate is projected onto the path; reference points are laid along it
  at the arc lengths the car is expected to cover, ``s_k = s_0 + sum v_j dt`` with ``v_j``
  the speeds of the warm start (the previous plan, or the current speed on the first step).
  This replaces a cubic fitted to the waypoints in the vehicle frame; the path is already a spline.
* Cost (the exact form is in :mod:`tracker.config`): cross-track error measured
  from each reference point's tangent, heading error (the path yaw is unwrapped along the
  horizon and shifted by whole turns to within pi of the current yaw, so the difference is
  smooth and needs no wrapping inside the NLP), speed error to the reference's speed profile,
  acceleration and steering, and their rates; the first rate is taken against the
  previously applied command.
* Bounds: steering ``|delta| <= max_steer_rad`` (pi/8 by default), acceleration in
  ``[accel_min_mps2, accel_max_mps2]``, steering rate ``|delta_k - delta_{k-1}| <=
  max_steer_rate_radps dt``.
* Model limits (optional, ``NmpcModel.limits``): ``|h(x_k)| <= h_max`` at nodes 1..N, soft:
  the excess costs ``dt * weights.limit_excess * max(|h| - h_max, 0)^2`` (a quadratic
  exterior penalty, continuously differentiable), so a car already beyond a limit never
  makes the NLP infeasible, and the NLP gains no variables (slack variables doubled
  IPOPT's iterations, 5 -> 10 per step on the lane change, with the same result). The
  dynamic model keeps its tyres within their linear range this way.
* Initial state: the states the model reads from the estimate, by name
  (``NmpcModel.estimated_state_names``); the model's other states (e.g. the steering
  actuator's angle, which no estimator reports) are *internal*: the tracker carries them
  itself, propagating last step's state with the command it applied (exact for an
  actuator driven by that command), and starts them at rest at the last applied input.
* Latency: with ``latency_compensation`` the tracker believes the
  car receives each command ``latency_s`` after it was issued (the runner's delay line,
  ``plant.actuator_delay_s``), plus the actuator lag the model leaves out
  (``unmodelled_lag_s``, approximated as more delay). The estimate is predicted forward
  from its time to ``t_s`` plus that delay, piece by piece with the commands already on
  their way (:class:`tracker.mpc.delay_line.IssuedInputs`), not the last one held: the
  optimisation then decides the input the car applies once the delay has passed. The
  internal states are propagated with the same applied commands.
* Warm start: the previous solution shifted by the time elapsed; on the first step the
  last applied actuation held over the horizon and rolled out through the model (section
  1, "warm start").
* Failures: the solver status is checked every step. On failure, or on a non-finite
  result, the last good plan is replayed, shifted by the elapsed time (``fallback=True``);
  once failures have lasted longer than ``fallback_time_s`` the tracker commands a safe
  stop: steering back to zero at the steering-rate limit, then held, and a constant
  deceleration to standstill. :meth:`Nmpc.step` never raises for a solver failure.

* Solvers (``tracker.solver``; built once in the constructor, a step only sets parameters
  and solves; the solver's own verdict decides success, see :meth:`_Nlp.solve`):

  - ``ipopt``: interior point with a general sparse factorisation, on the
    variables in blocks ``[x_0 .. x_N, u_0 .. u_{N-1}]``; the steering-rate constraint
    couples neighbouring inputs.
  - ``fatrop`` (default): an interior point method for optimal control, one Riccati recursion over
    the stages per iteration. It needs the NLP stage by stage: ``[z_0, u_0, z_1, ..,
    z_N]`` with ``z_k = [x_k, u_{k-1}]``, the previous input carried as a state so the
    rate bound and the rate costs stay within a stage, the constraints ordered stage by
    stage (:meth:`Nmpc._staged_problem`). Same optimum as IPOPT (first commands within
    1e-7), same iteration count; each iteration is cheaper.
  - ``sqp-rti``: a real-time iteration (Diehl): ``rti_iterations`` (1) Gauss-Newton SQP
    steps per control step on the staged NLP, warm-started from the shifted plan, each one
    QP (``rti_qp_solver``: hpipm, a stage-wise Riccati interior point, by default). Not
    converged within a step (one step from a cold guess is 6e-4 off the optimum's first
    command) but converged along the run, since the warm start carries the iterate on.
    CasADi's ``sqpmethod`` with ``max_iter = 1`` would do the same, but it ignores a
    failed QP (:class:`_RealTimeIteration`), so the iteration is written out here.

  With ``tracker.compiled`` (fatrop only) the NLP's functions are C instead of CasADi's
  virtual machine: :meth:`Nmpc._staged_problem` in MX maps one stage function over the
  horizon, so the generated code holds each derivative once (0.8 MB of C, 13 s with
  ``gcc -O1`` on a loaded machine, against 4 MB and 88 s for the inlined SX NLP); the
  library is cached per machine, keyed by the code (model, belief, weights, horizon).
  The same NLP and iterates (plans equal to 1e-9, ``tests/tracker/mpc/test_nmpc_solvers.py``);
  the solve of the lane change about 2-3x faster (``bench/where_time_goes.py``).

  Measured with ``bench/solve_time.py`` (MuJoCo sedan, EKF, lane change; p50 and p99 of
  the per-step solve time, median over seeds 0/1/2; max CTE for seeds 0/1/2; 2 cores
  shared with other jobs under load, so every time is inflated, IPOPT's by about 1.5-2x
  against a quiet moment, and p99 mostly shows the scheduler, not the solver):

  ===================  ===============  ============  =========================  ========
  tracker              solver           p50/p99 [ms]  max CTE, seeds 0/1/2 [m]   failures
  ===================  ===============  ============  =========================  ========
  kinematic, N = 20    ipopt            3.50 / 11.2   0.7914 / 0.7499 / 0.7369   0
  kinematic, N = 20    fatrop           0.90 / 5.7    0.7914 / 0.7499 / 0.7369   0
  kinematic, N = 20    sqp-rti, hpipm   0.59 / 4.9    0.7914 / 0.7499 / 0.7369   0
  kinematic, N = 20    sqp-rti, qrqp    0.97 / 6.7    0.7914 / 0.7499 / 0.7369   0
  kinematic, N = 20    sqp-rti, osqp    0.76 / 1.4    0.7914 / 0.7499 / 0.7369   0
  kinematic, N = 25    ipopt            3.30 / 13.2   0.7972 / 0.7542 / 0.7366   0
  kinematic, N = 25    fatrop           1.10 / 6.2    0.7972 / 0.7542 / 0.7366   0
  kinematic, N = 25    sqp-rti, hpipm   0.65 / 5.1    0.7972 / 0.7543 / 0.7366   0
  dynamic, N = 25      ipopt            10.5 / 24.3   0.0575 / 0.0462 / 0.0469   0
  dynamic, N = 25      fatrop           3.12 / 12.1   0.0575 / 0.0462 / 0.0469   0
  dynamic, N = 25      sqp-rti, hpipm   0.92 / 5.5    0.0575 / 0.0462 / 0.0469   0
  dynamic, N = 25      sqp-rti, qrqp    2.48 / 10.8   0.0575 / 0.0462 / 0.0469   0
  dynamic, N = 25      sqp-rti, osqp    8.22 / 21.9   0.0575 / 0.0462 / 0.0469   0
  ===================  ===============  ============  =========================  ========

  In a quieter moment: kinematic N = 20 p50 2.4-2.5 ms with IPOPT, 0.82-1.1 ms with
  fatrop, 0.49-0.52 ms (p99 0.82 ms) with the RTI; dynamic 5.2 ms with IPOPT, 0.68-0.78
  ms with the RTI. Harder cases (dynamic-nmpc, seed 0, max CTE ipopt / fatrop / RTI):
  Falcone's unstretched path at 1.11 g 0.6734 / 0.6734 / 0.6704 m (the soft slip limits
  active), a 2000 kg car on friction 0.7 0.1584 m for all three, 100 ms actuator delay
  0.0735 m for all three; no failures. ``fatrop`` is the default: it gives IPOPT's
  optimum (the NLP the testbed was tuned against) 2-3 times faster; IPOPT stays
  selectable as the reference. The RTI's plans are one Gauss-Newton step, not an
  optimum (status ``RTI_Completed``), so it is not the default although it is as
  accurate on every case above and 6-10 times faster.

Nothing depends on wall-clock time except the reported ``solve_time_s``, so equal inputs
give equal outputs.
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import casadi as ca
import numpy as np

from cosim.core.compiled_function import CompiledCacheWarning, compiled_library
from cosim.core.exceptions import ConfigError
from cosim.core.records import Command, Estimate, Plan
from tracker.config import TrackerConfig
from tracker.mpc.delay_line import IssuedInputs
from tracker.mpc.fallback import (
    INPUT,
    INPUT_NAMES,
    FailureClock,
    first_command,
    safe_stop_inputs,
    shifted_inputs,
    shifted_states,
)
from tracker.mpc.grip_speed import CurvatureTable, capped_reference_speed
from tracker.mpc.horizon_reference import horizon_reference
from tracker.mpc.vector_layout import VectorLayout
from tracker.paths.reference_path import ReferencePath

REQUIRED_STATE_NAMES: tuple[str, ...] = ("x_m", "y_m", "yaw_rad", "vx_mps")
"""States the cost and the safe stop read: CoG position (world frame), yaw, forward speed."""

_TIME_EPS_S = 1e-9
"""Slack when comparing simulated times, against float round-off of sums of periods."""

_REFERENCE_BLOCKS: tuple[str, ...] = (
    "ref_x_m", "ref_y_m", "ref_yaw_rad", "ref_speed_mps", "ref_steer_rad")
"""The parameters of one reference point, in the order a stage takes them."""


@dataclass(frozen=True)
class NmpcModel:
    """A vehicle model as the shared NMPC needs it.

    ``step`` is ``F(state, inputs) -> next_state`` over one stage of ``dt_s``; ``predict``
    is ``P(state, inputs, duration_s) -> state`` for a variable duration (latency, elapsed
    time); both hold the inputs over the interval. ``estimated_state_names`` are read from
    the :class:`~cosim.core.records.Estimate` by name; every other state is internal and
    ``internal_rest_inputs`` names the input each one rests at (its value when nothing
    else is known). ``unmodelled_lag_s`` is the actuator lag the model lacks, added to the
    prediction over the latency.
    """

    name: str
    state_names: tuple[str, ...]
    estimated_state_names: tuple[str, ...]
    step: ca.Function
    predict: ca.Function
    dt_s: float
    unmodelled_lag_s: float = 0.0
    understeer_gradient_radpmps2: float = 0.0
    """K of the model's steady turn, ``delta = atan(L kappa) + K v^2 kappa`` (0: neutral)."""
    internal_rest_inputs: Mapping[str, str] = field(default_factory=dict)
    input_names: tuple[str, ...] = INPUT_NAMES
    limits: ca.Function | None = None
    """``h(state) -> limited quantities`` (e.g. tyre slip angles), or None."""
    limit_names: tuple[str, ...] = ()
    """Names of ``h``'s outputs, in order (units in the names)."""
    limit_bounds: tuple[float, ...] = ()
    """``h_max`` for each of ``h``'s outputs: the soft bound ``|h| <= h_max``."""
    stage_limits: ca.Function | None = None
    """``g(state, inputs) -> limited quantities`` of a stage's start node and its inputs
    (e.g. the tyres' friction usage, :mod:`tracker.models.tyre_limits`), or None."""
    stage_limit_names: tuple[str, ...] = ()
    """Names of ``g``'s outputs, in order."""
    stage_limit_bounds: tuple[float, ...] = ()
    """``g_max`` for each of ``g``'s outputs: the soft bound ``|g| <= g_max``."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "internal_rest_inputs",
                           MappingProxyType(dict(self.internal_rest_inputs)))
        if self.input_names != INPUT_NAMES:
            raise ConfigError(f"model {self.name}: inputs {self.input_names}, expected "
                              f"{INPUT_NAMES}")
        missing = [n for n in REQUIRED_STATE_NAMES if n not in self.state_names]
        if missing:
            raise ConfigError(f"model {self.name}: expected states {missing}")
        internal = set(self.state_names) - set(self.estimated_state_names)
        if set(self.estimated_state_names) - set(self.state_names):
            raise ConfigError(f"model {self.name}: estimated states must be model states")
        if internal != set(self.internal_rest_inputs):
            raise ConfigError(f"model {self.name}: internal states {sorted(internal)} need "
                              "a rest input each (internal_rest_inputs)")
        if set(self.internal_rest_inputs.values()) - set(INPUT_NAMES):
            raise ConfigError(f"model {self.name}: rest inputs must be among {INPUT_NAMES}")
        if not (math.isfinite(self.unmodelled_lag_s) and self.unmodelled_lag_s >= 0.0):
            raise ConfigError(f"model {self.name}: unmodelled_lag_s = "
                              f"{self.unmodelled_lag_s!r}: expected a number >= 0")
        n_limits = 0 if self.limits is None else self.limits.size1_out(0)
        if len(self.limit_names) != n_limits or len(self.limit_bounds) != n_limits:
            raise ConfigError(f"model {self.name}: expected {n_limits} limit names and bounds")
        if not all(math.isfinite(b) and b > 0.0 for b in self.limit_bounds):
            raise ConfigError(f"model {self.name}: limit bounds {self.limit_bounds}: expected "
                              "positive numbers")
        if self.limits is not None and (self.limits.n_in() != 1
                                        or self.limits.size1_in(0) != len(self.state_names)):
            raise ConfigError(f"model {self.name}: limits must be a function of the state")
        n_stage = 0 if self.stage_limits is None else self.stage_limits.size1_out(0)
        if (len(self.stage_limit_names) != n_stage
                or len(self.stage_limit_bounds) != n_stage):
            raise ConfigError(f"model {self.name}: expected {n_stage} stage limit names and "
                              "bounds")
        if not all(math.isfinite(b) and b > 0.0 for b in self.stage_limit_bounds):
            raise ConfigError(f"model {self.name}: stage limit bounds "
                              f"{self.stage_limit_bounds}: expected positive numbers")
        if self.stage_limits is not None and (
                self.stage_limits.n_in() != 2
                or self.stage_limits.size1_in(0) != len(self.state_names)
                or self.stage_limits.size1_in(1) != len(self.input_names)):
            raise ConfigError(f"model {self.name}: stage limits must be a function of the "
                              "state and the inputs")
        n_x, n_u = len(self.state_names), len(self.input_names)
        for function, n_in in ((self.step, 2), (self.predict, 3)):
            if (function.n_in() != n_in or function.size1_in(0) != n_x
                    or function.size1_in(1) != n_u or function.size1_out(0) != n_x):
                raise ConfigError(f"model {self.name}: {function.name()} does not match "
                                  f"{n_x} states and {n_u} inputs")


def _weighted_squares(terms: list[tuple[float, ca.SX]]) -> ca.SX:
    """``w_0 e_0^2 + w_1 e_1^2 + ...`` for ``(w, e)`` pairs, summed left to right."""
    total = None
    for weight, error in terms:
        term = weight * error**2
        total = term if total is None else total + term
    return total


@dataclass(frozen=True)
class _Solution:
    """What one solve produced (before :meth:`Nmpc.step` checks it is finite)."""

    w: np.ndarray
    cost: float
    status: str
    iterations: int
    success: bool
    solve_time_s: float


_QP_FEASIBILITY_TOL = 1e-3
"""Largest violation of a bound or a linearised constraint a real-time iteration's step
may leave (in the variables' and constraints' own units)."""


def _step_feasible(w: np.ndarray, g_linear: np.ndarray, nlp: _Nlp) -> bool:
    """Whether a QP's result honours the bounds and the linearised constraints: qrqp has
    reported success on an infeasible QP (with the friction ellipse's Hessian, an initial
    steering rate beyond its bound)."""
    tol = _QP_FEASIBILITY_TOL
    return bool(np.all(w >= nlp.lbx - tol) and np.all(w <= nlp.ubx + tol)
                and np.all(g_linear >= nlp.lbg - tol) and np.all(g_linear <= nlp.ubg + tol))


@dataclass(frozen=True)
class _RealTimeIteration:
    """Gauss-Newton SQP steps on the stage-wise NLP, each one structured QP (Diehl's
    real-time iteration), built once.

    ``qp_data(w, p) -> (H, grad f, g, J_g)``: the Gauss-Newton Hessian ``2 J_r' J_r`` of
    the cost's residuals, the cost gradient, the constraints and their Jacobian at the
    iterate ``w``; ``qp`` solves for the step ``dw``:
    ``min 1/2 dw' H dw + grad f' dw`` s.t. ``lbx <= w + dw <= ubx`` and
    ``lbg <= g + J_g dw <= ubg``; ``cost(w, p)`` is the NLP's cost at the result.

    CasADi's ``sqpmethod`` (``max_iter = 1``) does the same, but in CasADi 3.8 it carries
    on silently when a QP fails (``Maximum_Iterations_Exceeded`` either way) unless the QP
    raises, which dumps the whole QP to stdout; here every QP's status is checked.
    """

    qp_data: ca.Function
    qp: ca.Function
    cost: ca.Function
    iterations: int

    def solve(self, w: np.ndarray, params: np.ndarray, nlp: _Nlp) -> _Solution:
        """``iterations`` full steps from ``w`` within ``nlp``'s bounds; the first QP that
        fails ends it unsuccessfully (hpipm's status: 1 iteration limit, 2 step too small,
        3 NaN, 4 inconsistent equalities; qrqp and osqp report words)."""
        start = time.perf_counter()
        for iteration in range(1, self.iterations + 1):
            hessian, gradient, g, jacobian = self.qp_data(w, params)
            g = np.asarray(g, dtype=float).ravel()
            step = self.qp(h=hessian, g=gradient, a=jacobian, lbx=nlp.lbx - w,
                           ubx=nlp.ubx - w, lba=nlp.lbg - g, uba=nlp.ubg - g)
            stats = self.qp.stats()
            dw = np.asarray(step["x"], dtype=float).ravel()
            status = None
            if not stats.get("success", False):
                status = f"QP_Failed ({stats.get('return_status', 'unknown')})"
            elif not _step_feasible(w + dw, g + np.asarray(ca.mtimes(jacobian, dw)).ravel(),
                                    nlp):
                status = "QP_Failed (step violates the bounds)"
            if status is not None:
                return _Solution(w, math.nan, status, iteration, False,
                                 time.perf_counter() - start)
            w = w + dw
        cost = float(self.cost(w, params))
        return _Solution(w, cost, "RTI_Completed", self.iterations, True,
                         time.perf_counter() - start)


@dataclass(frozen=True)
class _Nlp:
    """One solver's NLP, built once: the solver, where the plan sits in its flat vector of
    variables ``w``, and the bounds (the parameters vary, nothing else does)."""

    solver_name: str
    """``tracker.solver``."""
    solver: ca.Function | _RealTimeIteration
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

    def solve(self, w0: np.ndarray, params: np.ndarray) -> _Solution:
        """Solve from the guess ``w0``; CasADi errors raise ``RuntimeError``.

        Success is each solver's own verdict: IPOPT's and fatrop's ``success`` (converged
        to ``tracker.tolerance``), the real-time iteration's every QP solved. The status
        is IPOPT's ``return_status``; fatrop's is an integer flag, reported as
        ``Solve_Succeeded`` (0) or ``fatrop_flag_<n>`` (1 both at the iteration limit and
        on an infeasible problem); the real-time iteration's ``RTI_Completed`` or
        ``QP_Failed (<the QP solver's status>)``.
        """
        if isinstance(self.solver, _RealTimeIteration):
            return self.solver.solve(w0, params, self)
        start = time.perf_counter()
        solution = self.solver(
            x0=w0, p=params, lbx=self.lbx, ubx=self.ubx, lbg=self.lbg, ubg=self.ubg
        )
        solve_time_s = time.perf_counter() - start
        stats = self.solver.stats()
        success = bool(stats.get("success", False))
        status = str(stats.get("return_status", "unknown"))
        if self.solver_name == "fatrop":
            status = "Solve_Succeeded" if success else f"fatrop_flag_{status}"
        return _Solution(np.asarray(solution["x"], dtype=float).ravel(),
                         float(solution["f"]), status, int(stats.get("iter_count", 0)),
                         success, solve_time_s)


@dataclass(frozen=True)
class _StagedProblem:
    """The NLP posed stage by stage (:meth:`Nmpc._staged_problem`), before a solver."""

    nlp: Mapping[str, ca.SX]
    """CasADi's NLP: variables ``x``, parameters ``p``, cost ``f``, constraints ``g``."""
    residuals: ca.SX
    """``r`` with ``f = |r|^2``: the weighted errors, for a Gauss-Newton Hessian."""
    structure: Mapping[str, object]
    """The stages' sizes as fatrop and hpipm take them: ``N``, ``nx``, ``nu``, ``ng``."""
    layout: Mapping[str, np.ndarray]
    """The :class:`_Nlp` fields other than the solver: indices and bounds."""

    def with_solver(self, solver_name: str,
                    solver: ca.Function | _RealTimeIteration) -> _Nlp:
        return _Nlp(solver_name, solver, **self.layout)


@dataclass(frozen=True)
class _Trajectory:
    """States (N+1 rows) and inputs (N rows) over the horizon starting at ``t_s``."""

    t_s: float
    states: np.ndarray
    inputs: np.ndarray


class Nmpc:
    """Nonlinear MPC path tracker on any :class:`NmpcModel` (Kong et al. 2015), solved by
    ``config.solver`` (IPOPT, fatrop or a real-time iteration; module docstring).

    Args:
      config: the tracker configuration (horizon, cost, bounds, solver, latency).
      model: the vehicle model; its ``dt_s`` must be ``config.dt_s``.

    The plan's node 0 is the state the optimisation started from: the estimate predicted
    over the latency (see the module docstring), i.e. the car at ``t_s + latency``; the
    plan's ``t_s`` and the command's ``t_s`` are the time of the step. A successful solve
    ends a fallback or a safe stop.
    """

    def __init__(self, config: TrackerConfig, model: NmpcModel) -> None:
        if not math.isclose(model.dt_s, config.dt_s, rel_tol=0.0, abs_tol=_TIME_EPS_S):
            raise ConfigError(f"model {model.name}: dt_s = {model.dt_s}, expected "
                              f"tracker.dt_s = {config.dt_s}")
        self.config = config
        self.model = model
        self.state_names: tuple[str, ...] = model.state_names
        self.input_names: tuple[str, ...] = model.input_names
        self._state = MappingProxyType({name: i for i, name in enumerate(model.state_names)})
        self._n_x = len(model.state_names)
        n = config.horizon
        self._n = n
        self._params = VectorLayout(
            (
                ("state0", self._n_x),
                ("input_prev", len(INPUT_NAMES)),
                ("ref_x_m", n),
                ("ref_y_m", n),
                ("ref_yaw_rad", n),
                ("ref_speed_mps", n),
                ("ref_steer_rad", n),
            )
        )
        builders = {
            "ipopt": self._build_ipopt,
            "fatrop": self._build_fatrop,
            "sqp-rti": self._build_sqp_rti,
        }
        if config.solver not in builders:
            raise ConfigError(f"tracker.solver = {config.solver!r}: expected one of "
                              f"{', '.join(repr(name) for name in builders)}")
        self._nlp = builders[config.solver]()
        latency_s = config.latency_s if config.latency_compensation else 0.0
        self._issued = IssuedInputs(latency_s + model.unmodelled_lag_s,
                                    np.zeros(len(INPUT_NAMES)))
        self._failures = FailureClock(config.fallback_time_s)
        self._curvature: CurvatureTable | None = None
        self.reset()

    # ------------------------------------------------------------------ construction

    def _stage_terms(
        self, u: ca.SX, previous: ca.SX, x: ca.SX, par: Mapping[str, ca.SX], k: int,
        x_start: ca.SX,
    ) -> tuple[list[tuple[float, ca.SX]], list[tuple[float, ca.SX]],
               list[tuple[float, ca.SX]]]:
        """The tracking cost of stage ``k``, as ``(weight per second, error)`` pairs.

        Returns the input terms (``u`` = u_k against ``previous`` = u_{k-1}), the tracking
        terms (``x`` = node k + 1 against reference point k) and the soft limits' excess
        vectors: the model's limits at node k + 1 (weight ``weights.limit_excess``) and its
        stage limits at ``x_start`` = node k with u_k (``weights.tyre_excess``); empty for
        a model without limits. Every solver's cost is ``dt * sum weight * error^2`` over
        them (``|excess|^2`` for a vector); the Gauss-Newton Hessian of the real-time
        iteration uses the errors.
        """
        w = self.config.weights
        dt = self.config.dt_s
        index = self._state
        accel_rate = (u[INPUT["accel_mps2"]] - previous[INPUT["accel_mps2"]]) / dt
        steer_rate_radps = (u[INPUT["steer_rad"]] - previous[INPUT["steer_rad"]]) / dt
        input_terms = [
            (w.accel, u[INPUT["accel_mps2"]]),
            (w.steer, u[INPUT["steer_rad"]] - par["ref_steer_rad"][k]),
            (w.accel_rate, accel_rate),
            (w.steer_rate, steer_rate_radps),
        ]
        ref_yaw = par["ref_yaw_rad"][k]
        dx = x[index["x_m"]] - par["ref_x_m"][k]
        dy = x[index["y_m"]] - par["ref_y_m"][k]
        cte = -ca.sin(ref_yaw) * dx + ca.cos(ref_yaw) * dy
        heading_error = x[index["yaw_rad"]] - ref_yaw
        speed_error = x[index["vx_mps"]] - par["ref_speed_mps"][k]
        tracking_terms = [(w.cte, cte), (w.heading, heading_error), (w.speed, speed_error)]
        excess = []
        if self.model.limits is not None:
            h = self.model.limits(x)
            excess.append((w.limit_excess,
                           ca.fmax(ca.fabs(h) - ca.DM(list(self.model.limit_bounds)), 0.0)))
        if self.model.stage_limits is not None:
            g = self.model.stage_limits(x_start, u)
            excess.append((w.tyre_excess,
                           ca.fmax(ca.fabs(g) - ca.DM(list(self.model.stage_limit_bounds)),
                                   0.0)))
        return input_terms, tracking_terms, excess

    def _input_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds of one stage's inputs (steering, acceleration)."""
        cfg = self.config
        low = np.empty(len(INPUT_NAMES))
        high = np.empty(len(INPUT_NAMES))
        low[INPUT["accel_mps2"]] = cfg.accel_min_mps2
        high[INPUT["accel_mps2"]] = cfg.accel_max_mps2
        low[INPUT["steer_rad"]] = -cfg.max_steer_rad
        high[INPUT["steer_rad"]] = cfg.max_steer_rad
        return low, high

    def _variable_bounds(self, size: int, input_index: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray]:
        """Box bounds on the inputs; every other variable is free."""
        low_input, high_input = self._input_bounds()
        lbx, ubx = np.full(size, -np.inf), np.full(size, np.inf)
        lbx[input_index] = low_input
        ubx[input_index] = high_input
        return lbx, ubx

    def _build_ipopt(self) -> _Nlp:
        """The multiple-shooting NLP for IPOPT (the tracking cost and the model).

        Variables ``[x_0 .. x_N, u_0 .. u_{N-1}]``; constraints: the initial state, the
        dynamics, the steering rate against the previous input (``input_prev`` for u_0).
        """
        cfg = self.config
        n, dt = self._n, cfg.dt_s
        n_u = len(INPUT_NAMES)
        states = ca.SX.sym("states", self._n_x, n + 1)
        inputs = ca.SX.sym("inputs", n_u, n)
        p = ca.SX.sym("p", self._params.size)
        par = self._params.split(p)

        cost = 0
        dynamics = []
        steer_rate = []
        previous = par["input_prev"]
        for k in range(n):
            u = inputs[:, k]
            dynamics.append(states[:, k + 1] - self.model.step(states[:, k], u))
            steer_rate.append(u[INPUT["steer_rad"]] - previous[INPUT["steer_rad"]])
            input_terms, tracking_terms, excess = self._stage_terms(
                u, previous, states[:, k + 1], par, k, states[:, k])
            cost += dt * _weighted_squares(input_terms)
            # Tracking terms at node k + 1 against reference point k (nodes 1..N).
            cost += dt * _weighted_squares(tracking_terms)
            for weight, vector in excess:
                cost += dt * weight * ca.sumsqr(vector)
            previous = u

        constraints = VectorLayout(
            (
                ("initial_state", self._n_x),
                ("dynamics", self._n_x * n),
                ("steer_rate", n),
            )
        )
        constraint_blocks = {
            "initial_state": states[:, 0] - par["state0"],
            "dynamics": ca.vertcat(*dynamics),
            "steer_rate": ca.vertcat(*steer_rate),
        }
        g = ca.vertcat(*(constraint_blocks[name] for name in constraints.slices))
        variables = ca.vertcat(ca.vec(states), ca.vec(inputs))
        options = {
            "print_time": False,
            "error_on_fail": False,
            "ipopt.print_level": 0,
            "ipopt.sb": "yes",
            "ipopt.max_iter": cfg.max_iterations,
            "ipopt.tol": cfg.tolerance,
        }
        solver = ca.nlpsol(
            self.model.name.replace("-", "_"), "ipopt",
            {"x": variables, "p": p, "f": cost, "g": g}, options,
        )
        n_states = self._n_x * (n + 1)
        state_index = np.arange(n_states).reshape(n + 1, self._n_x)
        input_index = n_states + np.arange(n_u * n).reshape(n, n_u)
        lbx, ubx = self._variable_bounds(variables.size1(), input_index)

        rate_step = cfg.max_steer_rate_radps * dt
        sizes = {name: s.stop - s.start for name, s in constraints.slices.items()}
        low = {
            "initial_state": np.zeros(sizes["initial_state"]),
            "dynamics": np.zeros(sizes["dynamics"]),
            "steer_rate": np.full(sizes["steer_rate"], -rate_step),
        }
        high = dict(low, steer_rate=np.full(sizes["steer_rate"], rate_step))
        return _Nlp(cfg.solver, solver, state_index, input_index,
                    np.empty((0, n_u), dtype=int), lbx, ubx,
                    constraints.pack(low), constraints.pack(high))

    def _stage_function(self) -> ca.Function:
        """Stage ``k`` of the stage-wise NLP, the same function for every ``k``.

        ``(z_k, u_k, z_{k+1}, r_k) -> (cost, dynamics, steering rate, residuals)`` with
        ``z_k = [x_k, c_k]`` (:meth:`_staged_problem`), ``r_k`` reference point ``k``
        (:data:`_REFERENCE_BLOCKS`), the stage's cost (:meth:`_stage_terms`), the
        dynamics residual ``z_{k+1} - [F(x_k, u_k), u_k]``, the steering-rate row
        ``delta_k - c_k[delta]`` and the cost's weighted residuals (the real-time
        iteration's Gauss-Newton Hessian).
        """
        cfg = self.config
        dt, n_x, n_u = cfg.dt_s, self._n_x, len(INPUT_NAMES)
        z = ca.SX.sym("z", n_x + n_u)
        u = ca.SX.sym("u", n_u)
        z_next = ca.SX.sym("z_next", n_x + n_u)
        ref = ca.SX.sym("ref", len(_REFERENCE_BLOCKS))
        point = {name: ref[i:i + 1] for i, name in enumerate(_REFERENCE_BLOCKS)}
        input_terms, tracking_terms, excess = self._stage_terms(
            u, z[n_x:], z_next[:n_x], point, 0, z[:n_x])
        cost = dt * _weighted_squares(input_terms) + dt * _weighted_squares(tracking_terms)
        residuals = [math.sqrt(dt * weight) * error
                     for weight, error in input_terms + tracking_terms]
        for weight, vector in excess:
            cost += dt * weight * ca.sumsqr(vector)
            residuals.append(math.sqrt(dt * weight) * vector)
        dynamics = z_next - ca.vertcat(self.model.step(z[:n_x], u), u)
        steer_rate = u[INPUT["steer_rad"]] - z[n_x + INPUT["steer_rad"]]
        return ca.Function("stage", [z, u, z_next, ref],
                           [cost, dynamics, steer_rate, ca.vertcat(*residuals)])

    def _staged_problem(self, symbol: type = ca.SX) -> _StagedProblem:
        """The same NLP posed stage by stage, for the structure-exploiting solvers.

        Stage ``k`` holds ``z_k = [x_k, c_k]`` and ``u_k`` (``z_N`` alone), where
        ``c_k = u_{k-1}`` carries the previous input as a state (``c_0 = input_prev``), so
        the steering-rate bound ``|delta_k - c_k[delta]| <= rate dt`` and the rate costs
        involve one stage only. Variables ``[z_0, u_0, z_1, u_1, .., z_N]``; constraint
        rows, stage by stage, the dynamics ``z_{k+1} - [F(x_k, u_k), u_k]`` (the identity
        on ``z_{k+1}`` fatrop and hpipm look for), then the stage's own constraints: the
        initial state ``z_0 = [state0, input_prev]`` (stage 0), the steering rate.

        The cost is the same sum of stage terms as IPOPT's (:meth:`_stage_terms`), so
        the optimum is the same; only the variables' order and two extra states per stage
        differ, which :class:`_Nlp` hides from the rest of the tracker. Every stage is
        :meth:`_stage_function` mapped over the horizon: with ``symbol = ca.SX`` the
        expressions are inlined (CasADi's virtual machine evaluates them fastest); with
        ``ca.MX`` they stay calls of one function, whose derivatives CasADi then
        generates once, not once per stage (C code a tenth the size, for compiling).
        """
        cfg = self.config
        n, dt, n_x = self._n, cfg.dt_s, self._n_x
        n_u = len(INPUT_NAMES)
        n_z = n_x + n_u
        stage_size = n_z + n_u
        p = symbol.sym("p", self._params.size)
        par = self._params.split(p)
        x = symbol.sym("w", stage_size * n + n_z)
        stages = ca.reshape(x[:stage_size * n], stage_size, n)
        z = ca.horzcat(stages[:n_z, :], x[stage_size * n:])
        references = ca.horzcat(*(par[name] for name in _REFERENCE_BLOCKS)).T
        costs, dynamics, steer_rates, residuals = self._stage_function().map(n)(
            z[:, :n], stages[n_z:, :], z[:, 1:], references)
        rate_step = cfg.max_steer_rate_radps * dt

        rows, lbg, ubg = [], [], []
        for k in range(n):
            stage_rows = [(dynamics[:, k], 0.0, 0.0)]
            if k == 0:
                stage_rows.append(
                    (z[:, 0] - ca.vertcat(par["state0"], par["input_prev"]), 0.0, 0.0))
            stage_rows.append((steer_rates[k], -rate_step, rate_step))
            for row, low, high in stage_rows:
                rows.append(row)
                lbg.append(np.full(row.size1(), low))
                ubg.append(np.full(row.size1(), high))
        nlp = {"x": x, "p": p, "f": ca.sum2(costs), "g": ca.vertcat(*rows)}

        starts = stage_size * np.arange(n + 1)
        state_index = starts[:, None] + np.arange(n_x)
        carried_index = starts[:, None] + np.arange(n_x, n_z)
        input_index = starts[:-1, None] + np.arange(n_z, stage_size)
        lbx, ubx = self._variable_bounds(x.size1(), input_index)
        structure = MappingProxyType({
            "N": n,
            "nx": [n_z] * (n + 1),
            "nu": [n_u] * n + [0],
            "ng": [n_z + 1] + [1] * (n - 1) + [0],
        })
        layout = MappingProxyType({
            "state_index": state_index, "input_index": input_index,
            "carried_index": carried_index, "lbx": lbx, "ubx": ubx,
            "lbg": np.concatenate(lbg), "ubg": np.concatenate(ubg),
        })
        return _StagedProblem(MappingProxyType(nlp), ca.vec(residuals), structure, layout)

    def _build_fatrop(self) -> _Nlp:
        """The stage-wise NLP (:meth:`_staged_problem`) for fatrop, a structure-exploiting
        interior-point method: the same optimum as IPOPT, each iteration a Riccati
        recursion over the stages instead of a general sparse factorisation.

        With ``tracker.compiled`` the NLP's functions (cost, constraints, their
        derivatives, the Lagrangian's Hessian) are generated as C from the mapped stage
        function, compiled once per machine (:func:`cosim.core.compiled_function.compiled_library`,
        ``-O1``: as fast as ``-O2`` here, half the compile time) and loaded by fatrop in
        place of CasADi's virtual machine; the same NLP, so the same iterates.
        """
        cfg = self.config
        # The warm start (the previous plan shifted) is near the optimum, so the barrier
        # starts small: mu_init = 1e-3 instead of fatrop's 0.1 takes 3 iterations instead
        # of 5 (median, lane change) to the same optimum. Its warm_start_init_point (the
        # multipliers too) failed a solve on the bench.
        options = {
            "print_time": False,
            "error_on_fail": False,
            "structure_detection": "manual",
            "fatrop": {"print_level": 0, "max_iter": cfg.max_iterations,
                       "tol": cfg.tolerance, "mu_init": 1e-3},
        }
        name = self.model.name.replace("-", "_")
        if cfg.compiled:
            problem = self._staged_problem(ca.MX)
            options.update(problem.structure)
            oracle = ca.nlpsol(name, "fatrop", dict(problem.nlp), options)
            # The NLP itself ("nlp": x, p -> f, g) and what the solver derived from it.
            functions = [oracle.oracle(), *map(oracle.get_function, oracle.get_function())]
            library = compiled_library(f"nmpc_{name}", functions, ("-O1",))
            if library is not None:
                try:
                    solver = ca.nlpsol(name, "fatrop", str(library), options)
                except RuntimeError as error:  # checked, so only a changing file gets here
                    first = (str(error).strip().splitlines() or [""])[-1]
                    warnings.warn(f"cannot load the compiled NLP {str(library)!r} ({first}): "
                                  "using CasADi's virtual machine", CompiledCacheWarning,
                                  stacklevel=2)
                else:
                    return problem.with_solver(cfg.solver, solver)
        problem = self._staged_problem()
        options.update(problem.structure)
        solver = ca.nlpsol(name, "fatrop", dict(problem.nlp), options)
        return problem.with_solver(cfg.solver, solver)

    def _build_sqp_rti(self) -> _Nlp:
        """The stage-wise NLP (:meth:`_staged_problem`) for a real-time iteration.

        Exactly ``rti_iterations`` full Gauss-Newton SQP steps (no line search) from the
        warm start, the previous plan shifted (:class:`_RealTimeIteration`). Each step
        solves one QP with the model linearised along the current iterate and the
        Hessian ``2 J_r' J_r`` of the cost's residuals: positive semi-definite, block
        diagonal by stage, no multipliers needed. One step does not converge the NLP;
        the iterate converges over successive control steps instead, as the warm start
        carries it forward.
        """
        cfg = self.config
        problem = self._staged_problem()
        w, p, cost, g = (problem.nlp[key] for key in ("x", "p", "f", "g"))
        residual_jacobian = ca.jacobian(problem.residuals, w)
        hessian = 2.0 * ca.mtimes(residual_jacobian.T, residual_jacobian)
        constraint_jacobian = ca.jacobian(g, w)
        qp_data = ca.Function(
            "rti_qp_data", [w, p],
            [hessian, ca.gradient(cost, w), g, constraint_jacobian],
        )
        # hpipm: CasADi gives every variable a box, an infinite bound becoming 1e8, and
        # then the relative stopping tests of hpipm's modes speed/balance never pass (50
        # iterations); speed_abs stops on the absolute complementarity and matches qrqp's
        # step to 6e-9 in 5-8 iterations. osqp's default tolerance (1e-3) left 1.2 cm of
        # steady error on the dynamic bench; 1e-6 leaves none.
        options: dict[str, object] = {"error_on_fail": False}
        if cfg.rti_qp_solver == "hpipm":
            options.update(problem.structure)
            options["hpipm"] = {"mode": "speed_abs", "iter_max": 50}
        elif cfg.rti_qp_solver == "qrqp":
            options.update(print_iter=False, print_header=False, print_info=False)
        elif cfg.rti_qp_solver == "osqp":
            options["osqp"] = {"verbose": False, "eps_abs": 1e-6, "eps_rel": 1e-6,
                               "max_iter": 10000}
        else:
            raise ConfigError(f"tracker.rti_qp_solver = {cfg.rti_qp_solver!r}: expected "
                              "one of 'hpipm', 'qrqp', 'osqp'")
        qp = ca.conic(
            "rti_qp", cfg.rti_qp_solver,
            {"h": hessian.sparsity(), "a": constraint_jacobian.sparsity()}, options,
        )
        rti = _RealTimeIteration(qp_data, qp, ca.Function("rti_cost", [w, p], [cost]),
                                 cfg.rti_iterations)
        return problem.with_solver(cfg.solver, rti)

    # ------------------------------------------------------------------ public API

    def reset(self, previous_command: Command | None = None) -> None:
        """Forget every previous solution.

        ``previous_command`` is the actuation already applied to the car (default: zero
        acceleration and steering); the first step warm-starts from it held over the
        horizon, penalises its first input rate against it and starts
        the internal states (the actuator) at rest at it.
        """
        previous = np.zeros(len(INPUT_NAMES))
        if previous_command is not None:
            previous[INPUT["accel_mps2"]] = previous_command.accel_mps2
            previous[INPUT["steer_rad"]] = previous_command.steer_rad
        self._previous_input = previous
        self._previous_t_s: float | None = None
        self._warm: _Trajectory | None = None
        self._last_good: _Trajectory | None = None
        self._last_state: tuple[float, np.ndarray] | None = None
        self._issued.reset(previous)
        self._failures.reset()

    def step(
        self, t_s: float, estimate: Estimate, reference: ReferencePath
    ) -> tuple[Command, Plan]:
        """One control step: the command to apply at ``t_s`` and the plan behind it."""
        state0 = self._initial_state(t_s, estimate)
        if not np.all(np.isfinite(state0)):
            return self._fallback(t_s, state0, "non_finite_estimate", 0, 0.0)
        guess = self._initial_guess(t_s, state0)

        blocks, speed_reduced = self._reference_blocks(reference, state0, guess.states, t_s)
        blocks["state0"] = state0
        blocks["input_prev"] = self._previous_input
        params = self._params.pack(blocks)
        nlp = self._nlp
        w0 = nlp.pack(guess.states, guess.inputs, self._previous_input)

        start = time.perf_counter()
        try:
            solution = nlp.solve(w0, params)
        except RuntimeError as error:  # CasADi evaluation errors: treat as a failed solve.
            solve_time_s = time.perf_counter() - start
            return self._fallback(t_s, state0, f"error: {error}", 0, solve_time_s)
        w, cost = solution.w, solution.cost
        if not (solution.success and np.all(np.isfinite(w)) and math.isfinite(cost)):
            return self._fallback(t_s, state0, solution.status, solution.iterations,
                                  solution.solve_time_s)

        states = w[nlp.state_index]
        inputs = self._clip_inputs(w[nlp.input_index])
        trajectory = _Trajectory(t_s, states, inputs)
        self._last_good = trajectory
        self._failures.reset()
        plan = self._plan(trajectory, cost, solution.solve_time_s, solution.iterations,
                          solution.status, True, False, speed_reduced)
        return self._commit(trajectory), plan

    # ------------------------------------------------------------------ helpers

    def _predict(self, state: np.ndarray, start_s: float, end_s: float) -> np.ndarray:
        """``state`` at ``start_s`` moved to ``end_s`` with the commands the car applies."""
        for duration_s, inputs in self._issued.segments(start_s, end_s):
            state = np.asarray(self.model.predict(state, inputs, duration_s),
                               dtype=float).ravel()
        return state

    def _internal_states(self, t_s: float) -> dict[str, float]:
        """The internal states at ``t_s``: last step's state propagated with the commands
        applied since (exact for an actuator they drive), else at rest at the command
        applied now."""
        applied = self._issued.applied_at(t_s)
        rest = {name: float(applied[INPUT[input_name]])
                for name, input_name in self.model.internal_rest_inputs.items()}
        if not rest or self._last_state is None:
            return rest
        last_t_s, last_state = self._last_state
        filled = np.where(np.isfinite(last_state), last_state, 0.0)
        state = self._predict(filled, last_t_s, t_s)
        values = {name: float(state[self._state[name]]) for name in rest}
        return values if all(math.isfinite(v) for v in values.values()) else rest

    def _initial_state(self, t_s: float, estimate: Estimate) -> np.ndarray:
        """The estimate's states and the internal ones, predicted over the estimate's age,
        the latency and the model's unmodelled lag."""
        missing = [name for name in self.model.estimated_state_names if name not in estimate]
        if missing:
            raise ConfigError(f"tracker model {self.model.name}: the estimate has no "
                              f"{', '.join(missing)}: expected an estimator that reports them")
        state = np.full(self._n_x, np.nan)
        for name in self.model.estimated_state_names:
            state[self._state[name]] = estimate[name]
        for name, value in self._internal_states(estimate.t_s).items():
            state[self._state[name]] = value
        self._last_state = (estimate.t_s, state.copy())
        self._issued.forget_before(estimate.t_s)
        if np.all(np.isfinite(state)):
            state = self._predict(state, estimate.t_s,
                                  max(t_s, estimate.t_s) + self._issued.delay_s)
        return state

    def _rollout(self, state0: np.ndarray, inputs: np.ndarray) -> np.ndarray:
        states = np.empty((inputs.shape[0] + 1, self._n_x))
        states[0] = state0
        for k, u in enumerate(inputs):
            states[k + 1] = np.asarray(self.model.step(states[k], u), dtype=float).ravel()
        return states

    def _initial_guess(self, t_s: float, state0: np.ndarray) -> _Trajectory:
        """Previous solution shifted by the elapsed time, else the last command held.

        ``state0`` must be finite.
        """
        if self._warm is None:
            inputs = np.tile(self._previous_input, (self._n, 1))
            return _Trajectory(t_s, self._rollout(state0, inputs), inputs)
        warm, dt_s = self._warm, self.config.dt_s
        states = shifted_states(warm.states, warm.inputs, warm.t_s, t_s, dt_s,
                                self.model.step, state0, self._state["yaw_rad"])
        return _Trajectory(t_s, states, shifted_inputs(warm.inputs, warm.t_s, t_s, dt_s))

    def _reference_blocks(
        self, reference: ReferencePath, state0: np.ndarray, guess_states: np.ndarray,
        t_s: float,
    ) -> tuple[dict[str, np.ndarray], bool]:
        """Reference points at the arc lengths the warm start expects to cover
        (:mod:`tracker.mpc.horizon_reference`), the reference speed there (the path's speed
        profile at each stage's arc length and time, capped by the friction-limited speed
        of the path ahead with ``grip.speed_planning``, :mod:`tracker.mpc.grip_speed`), and
        the steering they need in a steady turn; and whether the cap lowered the speed."""
        cfg = self.config
        index = self._state
        speed = guess_states[:, index["vx_mps"]]
        points = horizon_reference(cfg.reference, reference, state0[index["x_m"]],
                                   state0[index["y_m"]], state0[index["yaw_rad"]], speed,
                                   cfg.dt_s)
        steer = np.zeros(self._n)
        if cfg.curvature_feedforward:
            kappa = points.curvature_1pm
            steer = (np.arctan(cfg.model.wheelbase_m * kappa)
                     + self.model.understeer_gradient_radpmps2 * speed[1:] ** 2 * kappa)
        ref_speed = points.speed_mps(reference, t_s, cfg.dt_s)
        speed_reduced = False
        if cfg.grip.speed_planning:
            if self._curvature is None or self._curvature.path is not reference:
                self._curvature = CurvatureTable(reference)  # once per path
            cap = capped_reference_speed(self._curvature, points.s_m, ref_speed,
                                         float(state0[index["vx_mps"]]),
                                         cfg.model.tire_friction, cfg.grip)
            ref_speed, speed_reduced = cap.speed_mps, cap.reduced
        return {
            "ref_x_m": points.x_m,
            "ref_y_m": points.y_m,
            "ref_yaw_rad": points.yaw_rad,
            "ref_speed_mps": ref_speed,
            "ref_steer_rad": steer,
        }, speed_reduced

    def _clip_inputs(self, inputs: np.ndarray) -> np.ndarray:
        """A solver may end a hair outside a bound; the command never does."""
        low, high = self._input_bounds()
        return np.clip(inputs, low, high)

    def _commit(self, trajectory: _Trajectory) -> Command:
        """Apply the trajectory's first input: remember it and keep the rest as warm start."""
        first = trajectory.inputs[0]
        self._previous_input = first.copy()
        self._previous_t_s = trajectory.t_s
        self._issued.record(trajectory.t_s, first)
        self._warm = trajectory
        return first_command(trajectory.t_s, trajectory.inputs)

    def _fallback(
        self, t_s: float, state0: np.ndarray, status: str, iterations: int, solve_time_s: float
    ) -> tuple[Command, Plan]:
        """Replay the last good plan shifted; after ``fallback_time_s``, a safe stop."""
        if self._failures.fail(t_s):
            cfg = self.config
            first_period_s = cfg.dt_s if self._previous_t_s is None else t_s - self._previous_t_s
            inputs = safe_stop_inputs(
                self._n, cfg.dt_s, first_period_s,
                steer_rad=float(self._previous_input[INPUT["steer_rad"]]),
                speed_mps=float(state0[self._state["vx_mps"]]),
                max_steer_rate_radps=cfg.max_steer_rate_radps,
                accel_mps2=cfg.safe_stop_accel_mps2,
            )
            status = f"safe_stop ({status})"
        elif self._last_good is not None:
            inputs = shifted_inputs(self._last_good.inputs, self._last_good.t_s, t_s,
                                    self.config.dt_s)
            status = f"fallback ({status})"
        else:
            inputs = np.tile(self._previous_input, (self._n, 1))
            status = f"fallback ({status})"
        inputs = self._clip_inputs(inputs)
        if np.all(np.isfinite(state0)):
            states = self._rollout(state0, inputs)
        else:
            states = np.full((self._n + 1, self._n_x), np.nan)
        trajectory = _Trajectory(t_s, states, inputs)
        plan = self._plan(trajectory, math.nan, solve_time_s, iterations, status, False, True)
        command = self._commit(trajectory)
        if not np.all(np.isfinite(states)):
            self._warm = None  # never warm-start from a non-finite guess
        return command, plan

    def _plan(
        self,
        trajectory: _Trajectory,
        cost: float,
        solve_time_s: float,
        iterations: int,
        status: str,
        success: bool,
        fallback: bool,
        speed_reduced: bool = False,
    ) -> Plan:
        return Plan(
            t_s=trajectory.t_s,
            dt_s=self.config.dt_s,
            state_names=self.state_names,
            states=trajectory.states.copy(),
            input_names=self.input_names,
            inputs=trajectory.inputs.copy(),
            cost=cost,
            solve_time_s=solve_time_s,
            iterations=iterations,
            status=status,
            success=success,
            fallback=fallback,
            speed_reduced=speed_reduced,
        )
