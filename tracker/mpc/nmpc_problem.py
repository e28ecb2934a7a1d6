"""The NMPC's optimisation problem, posed once for a model and a configuration, and the
solver each ``tracker.solver`` puts on it.

The tracking cost and constraints are those of :mod:`tracker.mpc.nmpc` (module docstring):
``min sum_k c_k(x_k, u_k)`` by multiple shooting, ``x_{k+1} = F(x_k, u_k)``, ``x_0`` the
predicted estimate, the steering rate bounded against the previous input. Everything that
changes from step to step is a parameter (:attr:`NmpcProblem.params`): a step only sets
parameters and solves.

Solvers (``tracker.solver``; built once in the constructor, a step only sets parameters
and solves; the solver's own verdict decides success, see :meth:`tracker.mpc.nlp.Nlp.solve`):

- ``ipopt``: interior point with a general sparse factorisation, on the
  variables in blocks ``[x_0 .. x_N, u_0 .. u_{N-1}]``; the steering-rate constraint
  couples neighbouring inputs.
- ``fatrop`` (default): an interior point method for optimal control, one Riccati recursion over
  the stages per iteration. It needs the NLP stage by stage: ``[z_0, u_0, z_1, ..,
  z_N]`` with ``z_k = [x_k, u_{k-1}]``, the previous input carried as a state so the
  rate bound and the rate costs stay within a stage, the constraints ordered stage by
  stage (:meth:`NmpcProblem.staged_problem`). The same optimum as IPOPT, in as many
  iterations; each iteration is cheaper.
- ``sqp-rti``: a real-time iteration (Diehl): ``rti_iterations`` (1) Gauss-Newton SQP
  steps per control step on the staged NLP, warm-started from the shifted plan, each one
  QP (``rti_qp_solver``: hpipm, a stage-wise Riccati interior point, by default). Not
  converged within a step but converged along the run, since the warm start carries the
  iterate on; from a cold guess (the first step, after a reset or a non-finite plan) it
  iterates to ``tolerance``, so the run starts at the optimum.
  CasADi's ``sqpmethod`` with ``max_iter = 1`` would do the same, but it ignores a
  failed QP (:class:`~tracker.mpc.nlp.RealTimeIteration`), so the iteration is written out here.

With ``tracker.compiled`` the solver's work is C instead of CasADi's virtual machine,
generated once per machine and cached, keyed by the NLP's graph (model, horizon, solver
options); the belief and the weights are parameters, so one library serves them all:
for fatrop the inlined SX NLP of :meth:`NmpcProblem.staged_problem` and the derivatives
fatrop asks for; for sqp-rti with hpipm the whole step, the QP's data, hpipm's call and
the cost (:mod:`tracker.mpc.compiled_rti`). The same NLP and iterates
(``tests/tracker/mpc/test_nmpc_solvers.py``), solved faster (``bench/where_time_goes.py``).

Solve times and accuracy of each solver, and why the real-time iteration is not the
default: docs/defaults.md, NMPC solvers; ``bench/solve_time.py`` times them on
this machine.
"""

from __future__ import annotations

import ctypes
import json
import warnings
from collections.abc import Callable, Mapping
from dataclasses import fields
from pathlib import Path
from types import MappingProxyType, SimpleNamespace

import casadi as ca
import numpy as np

from cosim.core.compiled_function import CompiledCacheWarning, compiled_library, compiler
from cosim.core.exceptions import ConfigError
from tracker.config import TrackerConfig, TrackerWeights
from tracker.mpc.compiled_rti import (
    CompiledRtiStep,
    casadi_folder,
    complete_hpipm_options,
    hpipm_build_flags,
    hpipm_options_edit_digest,
    load_hpipm,
    rti_step_function,
)
from tracker.mpc.fallback import INPUT, INPUT_NAMES
from tracker.mpc.nlp import Nlp, RealTimeIteration, StagedProblem
from tracker.mpc.nmpc_model import NmpcModel
from tracker.mpc.tracking_cost import input_terms, tracking_terms, weighted_squares
from tracker.mpc.vector_layout import VectorLayout

WEIGHT_NAMES: tuple[str, ...] = tuple(field.name for field in fields(TrackerWeights))
"""``tracker.weights`` as the NLP's ``weights`` parameters take them, in vector order: every
weight is a parameter, so one NLP (and one compiled library) serves every weighting."""

TYRE_EXCESS_BLEND = 1e-3
"""``e`` of :func:`smooth_excess` for the friction usage (``u^2``, its bound 0.72 by default:
:mod:`tracker.models.tyre_limits`)."""


def smooth_excess(over: ca.SX, blend: float = TYRE_EXCESS_BLEND) -> ca.SX:
    """``max(over, 0)`` blended over ``blend``, ``(over + sqrt(over^2 + e^2)) / 2``: ``e / 2`` at
    the bound, within ``e^2 / (4 |over|)`` of the exact excess away from it. Its square, the
    penalty, has a continuous second derivative; the exact excess's jumps at the bound, and
    an optimum with a stage at the bound (a swerve at the grip's limit on a wet road) made
    fatrop's Newton steps cycle across the jump until its iteration limit."""
    return 0.5 * (over + ca.sqrt(over * over + blend * blend))


COMPILE_FLAGS = ("-O1",)
"""Optimisation of the compiled NLPs: as fast as ``-O2`` here, half the compile time."""

_REFERENCE_BLOCKS: tuple[str, ...] = (
    "ref_x_m", "ref_y_m", "ref_yaw_rad", "ref_speed_mps", "ref_steer_rad")
"""The parameters of one reference point, in the order a stage takes them."""


class NmpcProblem:
    """The NLP of an NMPC on ``model`` with ``config``'s horizon, cost, bounds and solver.

    :attr:`params` lays out the parameters a step sets (initial state, previous input,
    reference points); :meth:`build` makes the :class:`~tracker.mpc.nlp.Nlp` of
    ``config.solver``.
    """

    def __init__(self, config: TrackerConfig, model: NmpcModel) -> None:
        self.config = config
        self.model = model
        self._state = MappingProxyType({name: i for i, name in enumerate(model.state_names)})
        self._n_x = len(model.state_names)
        n = config.horizon
        self._n = n
        self.params = VectorLayout(
            (
                ("state0", self._n_x),
                ("input_prev", len(INPUT_NAMES)),
                ("ref_x_m", n),
                ("ref_y_m", n),
                ("ref_yaw_rad", n),
                ("ref_speed_mps", n),
                ("ref_steer_rad", n),
                ("belief", len(model.belief)),
                ("weights", len(WEIGHT_NAMES)),
            )
        )
        self.belief_values = np.array(model.belief, dtype=float)
        """The ``belief`` block of every solve's parameters (the model's numbers)."""
        self.weight_values = np.array([float(getattr(config.weights, name))
                                       for name in WEIGHT_NAMES])
        """The ``weights`` block (``tracker.weights``, :data:`WEIGHT_NAMES` order)."""

    def build(self) -> Nlp:
        """The NLP with the solver ``tracker.solver`` (IPOPT, fatrop or the real-time
        iteration), built once."""
        builders = {
            "ipopt": self.build_ipopt,
            "fatrop": self.build_fatrop,
            "sqp-rti": self.build_sqp_rti,
        }
        if self.config.solver not in builders:
            raise ConfigError(f"tracker.solver = {self.config.solver!r}: expected one of "
                              f"{', '.join(repr(name) for name in builders)}")
        return builders[self.config.solver]()

    def stage_terms(
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
        w = SimpleNamespace(**dict(zip(WEIGHT_NAMES, ca.vertsplit(par["weights"]),
                                       strict=True)))
        inputs = input_terms(u, previous, self.config.dt_s, w, par["ref_steer_rad"][k])
        tracking = tracking_terms(x, self._state, par["ref_x_m"][k], par["ref_y_m"][k],
                                  par["ref_yaw_rad"][k], par["ref_speed_mps"][k], w)
        excess = []
        limits = self.model.nlp_limits(x, par["belief"])
        if limits is not None:
            h, h_max = limits
            excess.append((w.limit_excess, ca.fmax(ca.fabs(h) - h_max, 0.0)))
        stage_limits = self.model.nlp_stage_limits(x_start, u, par["belief"])
        if stage_limits is not None:
            g, g_max = stage_limits
            excess.append((w.tyre_excess, smooth_excess(ca.fabs(g) - g_max)))
        return inputs, tracking, excess

    def input_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds of one stage's inputs (steering, acceleration)."""
        cfg = self.config
        low = np.empty(len(INPUT_NAMES))
        high = np.empty(len(INPUT_NAMES))
        low[INPUT["accel_mps2"]] = cfg.accel_min_mps2
        high[INPUT["accel_mps2"]] = cfg.accel_max_mps2
        low[INPUT["steer_rad"]] = -cfg.max_steer_rad
        high[INPUT["steer_rad"]] = cfg.max_steer_rad
        return low, high

    def variable_bounds(self, size: int, input_index: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray]:
        """Box bounds on the inputs; every other variable is free."""
        low_input, high_input = self.input_bounds()
        lbx, ubx = np.full(size, -np.inf), np.full(size, np.inf)
        lbx[input_index] = low_input
        ubx[input_index] = high_input
        return lbx, ubx

    def build_ipopt(self) -> Nlp:
        """The multiple-shooting NLP for IPOPT (the tracking cost and the model).

        Variables ``[x_0 .. x_N, u_0 .. u_{N-1}]``; constraints: the initial state, the
        dynamics, the steering rate against the previous input (``input_prev`` for u_0).
        """
        cfg = self.config
        n, dt = self._n, cfg.dt_s
        n_u = len(INPUT_NAMES)
        states = ca.SX.sym("states", self._n_x, n + 1)
        inputs = ca.SX.sym("inputs", n_u, n)
        p = ca.SX.sym("p", self.params.size)
        par = self.params.split(p)

        cost = 0
        dynamics = []
        steer_rate = []
        previous = par["input_prev"]
        for k in range(n):
            u = inputs[:, k]
            dynamics.append(states[:, k + 1]
                            - self.model.nlp_step(states[:, k], u, par["belief"]))
            steer_rate.append(u[INPUT["steer_rad"]] - previous[INPUT["steer_rad"]])
            input_terms, tracking_terms, excess = self.stage_terms(
                u, previous, states[:, k + 1], par, k, states[:, k])
            cost += dt * weighted_squares(input_terms)
            # Tracking terms at node k + 1 against reference point k (nodes 1..N).
            cost += dt * weighted_squares(tracking_terms)
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
        lbx, ubx = self.variable_bounds(variables.size1(), input_index)

        rate_step = cfg.max_steer_rate_radps * dt
        sizes = {name: s.stop - s.start for name, s in constraints.slices.items()}
        low = {
            "initial_state": np.zeros(sizes["initial_state"]),
            "dynamics": np.zeros(sizes["dynamics"]),
            "steer_rate": np.full(sizes["steer_rate"], -rate_step),
        }
        high = dict(low, steer_rate=np.full(sizes["steer_rate"], rate_step))
        return Nlp(cfg.solver, solver, state_index, input_index,
                    np.empty((0, n_u), dtype=int), lbx, ubx,
                    constraints.pack(low), constraints.pack(high))

    def stage_function(self) -> ca.Function:
        """Stage ``k`` of the stage-wise NLP, the same function for every ``k``.

        ``(z_k, u_k, z_{k+1}, r_k) -> (cost, dynamics, steering rate, residuals)`` with
        ``z_k = [x_k, c_k]`` (:meth:`staged_problem`), ``r_k`` reference point ``k``
        (:data:`_REFERENCE_BLOCKS`), the stage's cost (:meth:`stage_terms`), the
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
        belief = ca.SX.sym("belief", len(self.model.belief))
        weights = ca.SX.sym("weights", len(WEIGHT_NAMES))
        point.update(belief=belief, weights=weights)
        input_terms, tracking_terms, excess = self.stage_terms(
            u, z[n_x:], z_next[:n_x], point, 0, z[:n_x])
        cost = dt * weighted_squares(input_terms) + dt * weighted_squares(tracking_terms)
        residuals = [ca.sqrt(dt * weight) * error
                     for weight, error in input_terms + tracking_terms]
        for weight, vector in excess:
            cost += dt * weight * ca.sumsqr(vector)
            residuals.append(ca.sqrt(dt * weight) * vector)
        dynamics = z_next - ca.vertcat(self.model.nlp_step(z[:n_x], u, belief), u)
        steer_rate = u[INPUT["steer_rad"]] - z[n_x + INPUT["steer_rad"]]
        return ca.Function("stage", [z, u, z_next, ref, belief, weights],
                           [cost, dynamics, steer_rate, ca.vertcat(*residuals)])

    def staged_problem(self) -> StagedProblem:
        """The same NLP posed stage by stage, for the structure-exploiting solvers.

        Stage ``k`` holds ``z_k = [x_k, c_k]`` and ``u_k`` (``z_N`` alone), where
        ``c_k = u_{k-1}`` carries the previous input as a state (``c_0 = input_prev``), so
        the steering-rate bound ``|delta_k - c_k[delta]| <= rate dt`` and the rate costs
        involve one stage only. Variables ``[z_0, u_0, z_1, u_1, .., z_N]``; constraint
        rows, stage by stage, the dynamics ``z_{k+1} - [F(x_k, u_k), u_k]`` (the identity
        on ``z_{k+1}`` fatrop and hpipm look for), then the stage's own constraints: the
        initial state ``z_0 = [state0, input_prev]`` (stage 0), the steering rate.

        The cost is the same sum of stage terms as IPOPT's (:meth:`stage_terms`), so
        the optimum is the same; only the variables' order and two extra states per stage
        differ, which :class:`Nlp` hides from the rest of the tracker. Every stage is
        :meth:`stage_function` mapped over the horizon and inlined (SX): CasADi's virtual
        machine and the generated C both evaluate the flat expressions fastest (in C the
        Lagrangian's Hessian and the constraints' Jacobian take half the time of a mapped
        MX stage function's, whose C is a tenth the size and compiles in half the time).
        """
        cfg = self.config
        n, dt, n_x = self._n, cfg.dt_s, self._n_x
        n_u = len(INPUT_NAMES)
        n_z = n_x + n_u
        stage_size = n_z + n_u
        p = ca.SX.sym("p", self.params.size)
        par = self.params.split(p)
        x = ca.SX.sym("w", stage_size * n + n_z)
        stages = ca.reshape(x[:stage_size * n], stage_size, n)
        z = ca.horzcat(stages[:n_z, :], x[stage_size * n:])
        references = ca.horzcat(*(par[name] for name in _REFERENCE_BLOCKS)).T
        costs, dynamics, steer_rates, residuals = self.stage_function().map(n)(
            z[:, :n], stages[n_z:, :], z[:, 1:], references,
            ca.repmat(par["belief"], 1, n), ca.repmat(par["weights"], 1, n))
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
        lbx, ubx = self.variable_bounds(x.size1(), input_index)
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
        return StagedProblem(MappingProxyType(nlp), ca.vec(residuals), structure, layout)

    def build_fatrop(self) -> Nlp:
        """The stage-wise NLP (:meth:`staged_problem`) for fatrop, a structure-exploiting
        interior-point method: the same optimum as IPOPT, each iteration a Riccati
        recursion over the stages instead of a general sparse factorisation.

        With ``tracker.compiled`` the NLP's functions (cost, constraints, their
        derivatives, the Lagrangian's Hessian) are generated as C from the inlined NLP,
        compiled once per machine (:func:`cosim.core.compiled_function.compiled_library`,
        ``-O1``: as fast as ``-O2`` here, half the compile time) and loaded by fatrop in
        place of CasADi's virtual machine; the same NLP, so the same iterates.
        """
        cfg = self.config
        # The warm start (the previous plan shifted) is near the optimum, so the barrier
        # starts small: mu_init = 1e-3 instead of fatrop's 0.1 took 3 iterations instead
        # of 5 (median, lane change, at a tolerance of 1e-6) to the same optimum. Its
        # warm_start_init_point (the multipliers too) failed a solve on the bench.
        options = {
            "print_time": False,
            "error_on_fail": False,
            "structure_detection": "manual",
            "fatrop": {"print_level": 0, "max_iter": cfg.max_iterations,
                       "tol": cfg.tolerance, "mu_init": 1e-3},
        }
        name = self.model.name.replace("-", "_")
        problem = self.staged_problem()
        options.update(problem.structure)
        if cfg.compiled:

            def functions() -> list[ca.Function]:
                """The NLP itself ("nlp": x, p -> f, g) and what fatrop derives from it."""
                oracle = ca.nlpsol(name, "fatrop", dict(problem.nlp), options)
                return [oracle.oracle(), *map(oracle.get_function, oracle.get_function())]

            # The NLP's graph and the interface's options determine every derived function;
            # hashing them (about 1 ms) instead of the generated C (0.1 s) finds the cached
            # library. fatrop's own settings (tolerance, iteration limit, barrier) are read
            # when it solves, not compiled: they are not in the key, so a sweep over
            # tracker.tolerance or tracker.max_iterations builds one library.
            nlp = problem.nlp
            interface = {k: v for k, v in options.items() if k != "fatrop"}
            key = json.dumps(interface, sort_keys=True) + ca.Function(
                "nlp", [nlp["x"], nlp["p"]], [nlp["f"], nlp["g"]]).serialize()
            library = self._compiled_library(f"nmpc_{name}", functions, key, "NLP", 20)
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
        solver = ca.nlpsol(name, "fatrop", dict(problem.nlp), options)
        return problem.with_solver(cfg.solver, solver)

    def build_sqp_rti(self) -> Nlp:
        """The stage-wise NLP (:meth:`staged_problem`) for a real-time iteration.

        Exactly ``rti_iterations`` full Gauss-Newton SQP steps (no line search; from a
        cold guess, until converged: :meth:`RealTimeIteration.solve`) from the
        warm start, the previous plan shifted (:class:`RealTimeIteration`). Each step
        solves one QP with the model linearised along the current iterate and the
        Hessian ``2 J_r' J_r`` of the cost's residuals: positive semi-definite, block
        diagonal by stage, no multipliers needed. One step does not converge the NLP;
        the iterate converges over successive control steps instead, as the warm start
        carries it forward.
        """
        cfg = self.config
        problem = self.staged_problem()
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
        cost_function = ca.Function("rti_cost", [w, p], [cost])
        compiled = None
        if cfg.compiled and cfg.rti_qp_solver == "hpipm":
            compiled = self._compiled_rti(problem, qp_data, qp, cost_function, options)
        rti = RealTimeIteration(qp_data, qp, cost_function, cfg.rti_iterations,
                                cfg.max_iterations, cfg.tolerance, compiled)
        return problem.with_solver(cfg.solver, rti)

    def _compiled_rti(self, problem: StagedProblem, qp_data: ca.Function, qp: ca.Function,
                      cost: ca.Function, options: Mapping[str, object]
                      ) -> CompiledRtiStep | None:
        """The real-time iteration's step as C (:mod:`tracker.mpc.compiled_rti`), or None
        (with a warning) when it cannot be built or loaded."""
        step = rti_step_function(qp_data, qp, cost)
        # The step's graph (QP data, cost, the hpipm call with its options, the outputs)
        # and the edit made to its generated source determine the library.
        key = step.serialize() + hpipm_options_edit_digest()
        include, link = hpipm_build_flags()
        name = f"rti_{self.model.name.replace('-', '_')}"
        try:
            library = self._compiled_library(name, lambda: [step], key,
                                             "real-time iteration", 10,
                                             (*COMPILE_FLAGS, *include), link,
                                             complete_hpipm_options, (casadi_folder(),))
        except ValueError as error:  # another CasADi's generated code
            warnings.warn(f"cannot compile the real-time iteration ({error}): using "
                          "CasADi's virtual machine", CompiledCacheWarning, stacklevel=3)
            return None
        if library is None:
            return None
        layout = problem.layout
        try:
            load_hpipm()  # found by its soname whichever virtualenv built the library
            return CompiledRtiStep(ctypes.CDLL(str(library)), step, layout["lbx"],
                                   layout["ubx"], layout["lbg"], layout["ubg"])
        except (OSError, AttributeError) as error:  # checked, so only a changing file
            warnings.warn(f"cannot load the compiled real-time iteration {str(library)!r} "
                          f"({error}): using CasADi's virtual machine", CompiledCacheWarning,
                          stacklevel=3)
            return None

    def _compiled_library(self, name: str, functions: Callable[[], list[ca.Function]],
                          key: str, what: str, build_s: int,
                          flags: tuple[str, ...] = COMPILE_FLAGS,
                          link_flags: tuple[str, ...] = (),
                          edit_source: Callable[[str], str] | None = None,
                          relocatable: tuple[Path, ...] = ()) -> Path | None:
        """The library of ``functions`` compiled once per machine
        (:func:`cosim.core.compiled_function.compiled_library`, with a note saying it takes
        about ``build_s``), or None with a warning when no C compiler works or it cannot
        build them."""
        fallback = (f"the NMPC's {what} runs in CasADi's virtual machine, 2-4x slower "
                    "(tracker.compiled=false says so quietly)")
        library = compiled_library(
            name, functions, flags, key=key, link_flags=link_flags, edit_source=edit_source,
            relocatable=relocatable,
            note=f"compiling {self.model.name.replace('_', '-')}'s {what} to C "
                 f"(about {build_s} s)", fallback=fallback)
        if library is None and compiler() is None:  # a failed build has said why
            warnings.warn(f"no working C compiler (gcc, or $CC): {fallback}",
                          CompiledCacheWarning, stacklevel=3)
        return library
