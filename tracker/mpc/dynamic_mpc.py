"""Delta-u MPC on the dynamic bicycle in path coordinates.

The model is Rajamani's dynamic bicycle in path-error coordinates ("Vehicle Dynamics and
Control", 2nd ed., Springer 2012, sec. 2.3 and 2.5); the controller is a delta-u linear
MPC with prediction horizon ``Np`` and control horizon ``Nc`` (L. Wang, "Model Predictive
Control System Design and Implementation Using MATLAB", Springer 2009, ch. 1-3; input
increments as in Falcone et al., IEEE TCST 2007). "The reference design" below is the
project's target for this controller: ``Np = 10``, ``Nc = 2``, ``Ts = 0.1 s``, steering
within 15 deg, acceleration within +-3 m/s^2, ``|e1| <= 0.5 m``, ``|e2| <= 3 deg``, and
the bar it sets on the stretched double lane change at 20 m/s, on its own linear model
without noise: max lateral deviation 88 mm, max steering 9.5 deg, heading error below
3 deg, 18.3 m/s reached at 1.1 s.

At every control step

1. **Starting point.** The estimate (``x_m, y_m, yaw_rad, vx_mps, vy_mps,
   yaw_rate_radps``) is predicted forward over its age and the transport delay the tracker
   believes in (latency compensation) with the world-frame steered dynamic
   bicycle (:func:`tracker.models.steered_dynamic_bicycle.predict_function`), piece by piece with
   the commands the car is executing meanwhile (:class:`tracker.mpc.delay_line.IssuedInputs`).
   Two actuator states no estimator reports are carried by the tracker itself
   (:class:`ActuatorBelief`): the road-wheel angle the steering actuator has reached (the
   belief's ``steer_time_constant_s``) and the achieved acceleration ``ax`` of (P4), both
   propagated exactly with the commands applied since the last step. The predicted
   position is projected onto the path: ``e1`` the signed lateral error (positive left),
   ``e2 = yaw - path_yaw``. The path model's state is then
   :data:`tracker.models.path_error_bicycle.STATE_NAMES`.
2. **Model.** (P1)-(P7) of :mod:`tracker.models.path_error_bicycle`, linearised at the starting
   speed ``v0`` (LPV: the reference design re-linearises at the current ``v_x`` every step), RK4
   instead of the reference design's Euler (see there why). The desired yaw rate of each stage is
   ``psi_D' = v kappa(s)`` at the middle of the stage, with ``s`` the arc length the car
   is expected to reach and ``v`` its expected speed: the speed change the last plan
   predicted, added to ``v0`` (``v0`` held on the first step).
3. **QP** (the reference design's delta-u form). The state is augmented with the previous input, so
   the decision variables are the input increments over the control horizon,
   ``u_k = u_{k-1} + Delta u_k`` for ``k < Nc`` (``u_{-1}`` the command issued last). From
   ``Nc`` on the reference design holds the last move; by default here
   (``steer_after_control_horizon: path``) the acceleration is held and the steering keeps
   its offset from the path's Ackermann angle, ``delta_k = delta_{Nc-1} + atan(L
   kappa_k) - atan(L kappa_{Nc-1})`` with ``kappa_k`` the curvature at stage ``k``'s
   middle, so that two moves can plan into a bend and out of it (held, the steering the
   QP plans for the second swerve's end is the one it needs in its middle: the lateral
   error peaks as the swerve ends). The geometric angle, not the model's steady-state
   steering with its understeer term: that one, tried, made the tuning seeds' worst case
   worse (docs/defaults.md). The predicted states are affine in the increments (a
   condensed QP of ``2 Nc`` increments and ``3 Np`` slacks: 34 variables by default). Cost
   (:mod:`tracker.mpc.dynamic_mpc_config`)::

       J = sum_{j=1..Np} ||Y_j - Y_ref||_Q^2 + sum_{i<Nc} ||Delta u_i||_R^2 + slack terms

   with ``Y = [vx, e1, e2]``, ``Y_ref = [v_D,j, 0, 0]``: ``v_D,j`` the speed profile where
   and when node ``j`` is expected (preview: the reference design holds one ``v_D``, which
   lags a braking profile by the whole horizon). Hard bounds: steering within
   ``tracker.max_steer_rad`` (by default 15 deg for this tracker: the reference design's),
   acceleration within ``[tracker.accel_min_mps2, tracker.accel_max_mps2]`` (reference design:
   +-3 m/s^2), steering increments within ``max_steer_rate_radps`` times the time they
   span (the time since the last command for the first). Soft limits (the reference design's hard
   ones, softened so the QP is never infeasible): ``|e1| <= 0.5 m``, ``|e2| <= 3 deg``,
   ``0 <= vx <= 30 m/s``, with one slack per limit and node ``1..Np``, penalised squared
   and linearly with ``weight_slack``. The QP is one ``ca.qpsol`` built in the
   constructor with every step-dependent number (starting state, previous input, ``v0``,
   the desired yaw rates, the ``v_D,j``) as a parameter: a step only evaluates it.
4. **Failures** (:mod:`tracker.mpc.base`, the skeleton every MPC shares): a failed QP, a
   numerical error or a non-finite result never raises: the last good plan is replayed,
   shifted by the elapsed time (status ``fallback (...)``), then after
   ``tracker.fallback_time_s`` a safe stop (``safe_stop (...)``); ``success=False,
   fallback=True``.

The plan's states are the path-model states at nodes ``0..Np`` (node 0 is the predicted
starting point, at ``t_s`` plus the latency), its inputs the commands of the ``Np``
stages; ``dt_s`` is ``Ts``. Nothing depends on wall-clock time but ``solve_time_s``.

The choices (back-end HiGHS, a slack per node and limit, the weights, the reference
design's heading reference ``e2 = 0``, no actuator lag in the model) and the measurements
behind them: docs/defaults.md, ``dynamic-mpc``; today's accuracy: ``docs/trackers.md``.
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import casadi as ca
import numpy as np

from cosim.core.dense_function import DenseFunction, densified
from cosim.core.exceptions import ConfigError
from cosim.core.records import Estimate
from tracker.config import TrackerConfig
from tracker.models import path_error_bicycle as path_model
from tracker.models import steered_dynamic_bicycle as steered
from tracker.mpc.base import MpcTracker, Solved, Start, Trajectory
from tracker.mpc.dynamic_mpc_config import DynamicMpcConfig
from tracker.mpc.fallback import INPUT, INPUT_NAMES
from tracker.mpc.nlp import BufferedNlpCall
from tracker.mpc.vector_layout import VectorLayout
from tracker.paths.reference_path import Projection, ReferencePath, wrap_angle

TRACKER_NAME = "dynamic-mpc"
"""``tracker.name`` of this tracker."""

ESTIMATED_STATE_NAMES: tuple[str, ...] = steered.VEHICLE_STATE_NAMES
"""What the tracker reads from the estimate, by name."""

SOFT_LIMIT_NAMES: tuple[str, ...] = ("e1_m", "e2_rad", "vx_mps")
"""The path-model states with a soft limit (a slack at every node), in slack order."""

_MAX_PREDICTION_PIECE_S = 0.05
"""Longest piece the latency prediction integrates at once (predict_function's 4 RK4 steps)."""


@dataclass(frozen=True)
class _Backend:
    """How to drive one CasADi QP back-end (``conic`` plugin) and read its stats."""

    options: Callable[[int], dict[str, object]]
    """The plugin's options for an iteration limit: silent, limited."""
    iterations_key: str | None
    """Where the stats report the iteration count (None: not reported, logged as 0)."""
    status_names: Mapping[int, str] = field(default_factory=dict)
    """Names of an integer ``return_status``."""


_BACKENDS: Mapping[str, _Backend] = MappingProxyType({
    "highs": _Backend(
        lambda limit: {"highs": {"output_flag": False, "qp_iteration_limit": limit}},
        "qp_iteration_count"),
    "daqp": _Backend(
        lambda limit: {"daqp": {"iter_limit": limit}},
        None,
        MappingProxyType({1: "optimal", 2: "soft_optimal", -1: "infeasible", -2: "cycling",
                          -3: "unbounded", -4: "iteration_limit", -5: "nonconvex",
                          -6: "overdetermined_initial"})),
})
"""The back-ends ``tracker.dynamic_mpc.qp_solver`` can name."""


@dataclass(frozen=True)
class ActuatorBelief:
    """The actuators' states at ``t_s`` as the tracker believes them (no estimator reports
    them): propagated with the commands the car applied."""

    t_s: float
    road_wheel_angle_rad: float
    """Front road-wheel angle the steering actuator has reached [rad]."""
    accel_mps2: float
    """Achieved longitudinal acceleration, ``ax`` of (P4) [m/s^2]."""


PLAN_WORLD_NAMES: tuple[str, ...] = ("x_m", "y_m")
"""World positions appended to the plan's path-model states (not part of the model)."""


@dataclass(frozen=True)
class StartingPoint(Start):
    """Where the optimisation starts: the estimate predicted over its age and the latency,
    at ``t_s``, as a path-model state (:data:`tracker.models.path_error_bicycle.STATE_NAMES`)."""

    s_m: float = math.nan
    """Arc length of the predicted position's projection onto the path [m]."""


@dataclass(frozen=True)
class _Qp:
    """The QP of one step, built once: solver, layouts, constant bounds, trajectory."""

    solver: ca.Function
    trajectory: ca.Function
    """``(z, p) -> (states (Np+1)x6, inputs Np x2)``: the plan the QP's variables mean."""
    variables: VectorLayout
    params: VectorLayout
    constraints: VectorLayout
    lbg: np.ndarray
    ubg: np.ndarray

    @functools.cached_property
    def plan(self) -> DenseFunction:
        """:attr:`trajectory` on buffers bound once (the same numbers, nothing converted)."""
        return DenseFunction(densified(self.trajectory))

    @functools.cached_property
    def call(self) -> BufferedNlpCall:
        """The solver on numpy arrays bound once, the constant constraint bounds set
        (:class:`tracker.mpc.nlp.BufferedNlpCall`): the same solves, nothing converted."""
        return BufferedNlpCall(self.solver, {"lbg": self.lbg, "ubg": self.ubg})


class DynamicMpc(MpcTracker):
    """Delta-u linear MPC on the path-error dynamic bicycle with a CasADi QP.

    Args:
      config: the tracker configuration; ``config.dynamic_mpc`` holds the horizons, the
        weights, the limits and the QP back-end; ``config.model`` is the belief (mass,
        yaw inertia, CoG position, axle cornering stiffnesses, steering time constant).
    """

    state_names: tuple[str, ...] = path_model.STATE_NAMES

    def __init__(self, config: TrackerConfig) -> None:
        if config.name != TRACKER_NAME:
            raise ConfigError(f"name = {config.name!r}: DynamicMpc expects {TRACKER_NAME!r}")
        self.settings: DynamicMpcConfig = config.dynamic_mpc
        self._n_p = self.settings.prediction_horizon
        self._n_c = self.settings.control_horizon
        self._ts = self.settings.sample_time_s
        self._params = path_model.PathErrorParams.from_vehicle(
            config.model, self.settings.accel_time_constant_s)
        self._steered = steered.SteeredBicycleParams.from_vehicle(config.model)
        self._step_model = path_model.discrete_function(self._params, self._ts)
        self._predict_world = steered.predict_function(self._steered)
        low, high = np.empty(len(INPUT_NAMES)), np.empty(len(INPUT_NAMES))
        max_steer = config.max_steer_rad
        low[INPUT["accel_mps2"]] = config.accel_min_mps2
        high[INPUT["accel_mps2"]] = config.accel_max_mps2
        low[INPUT["steer_rad"]] = -max_steer
        high[INPUT["steer_rad"]] = max_steer
        self._input_low, self._input_high = low, high
        self.config = config
        self._qp = self._build_qp()
        super().__init__(config, self._ts, self._n_p, low, high, path_model.STATE["vx_mps"],
                         config.latency_s if config.latency_compensation else 0.0)
        self.reset()

    # ------------------------------------------------------------------ construction

    def _build_qp(self) -> _Qp:
        """The condensed delta-u QP (module docstring, item 3), built once."""
        cfg = self.settings
        n_p, n_c = self._n_p, self._n_c
        n_x, n_u = len(path_model.STATE_NAMES), len(INPUT_NAMES)
        state = path_model.STATE
        variables = VectorLayout((("increments", n_c * n_u),
                             ("slacks", len(SOFT_LIMIT_NAMES) * n_p)))
        params = VectorLayout((
            ("state0", n_x),
            ("input_prev", n_u),
            ("speed_lin_mps", 1),
            ("yaw_rate_ref_radps", n_p),
            ("speed_ref_mps", n_p),
            ("ackermann_steer_rad", n_p),
        ))
        constraints = VectorLayout(
            (("inputs", n_c * n_u),)
            + tuple((f"{name}_{side}", n_p) for name in SOFT_LIMIT_NAMES
                    for side in ("upper", "lower"))
        )
        z = ca.SX.sym("z", variables.size)
        p = ca.SX.sym("p", params.size)
        var, par = variables.split(z), params.split(p)
        increments = ca.reshape(var["increments"], n_u, n_c)  # column i: Delta u_i
        slacks = ca.reshape(var["slacks"], n_p, len(SOFT_LIMIT_NAMES))  # one per node 1..Np
        slack = {name: slacks[:, i] for i, name in enumerate(SOFT_LIMIT_NAMES)}

        # Rollout: x_{k+1} = F(x_k, u_k; v0, psi_D'_k), u_k = u_{k-1} + Delta u_k (k < Nc);
        # from Nc on the last move held, or its steering's offset from the path's
        # Ackermann angle held (steer_after_control_horizon).
        x, u = par["state0"], par["input_prev"]
        states, inputs, moved = [x], [], []
        ackermann = par["ackermann_steer_rad"]
        follows_path = cfg.steer_after_control_horizon == "path"
        for k in range(n_p):
            if k < n_c:
                u = u + increments[:, k]
                moved.append(u)
            elif follows_path:
                turn = ackermann[k] - ackermann[n_c - 1]
                u = moved[-1] + ca.vertcat(*(turn if name == "steer_rad" else 0.0
                                             for name in INPUT_NAMES))
            x = self._step_model(x, u, par["speed_lin_mps"], par["yaw_rate_ref_radps"][k])
            states.append(x)
            inputs.append(u)

        weight = {"vx_mps": cfg.weight_speed, "e1_m": cfg.weight_lateral,
                  "e2_rad": cfg.weight_heading}
        cost = 0
        for j, x_j in enumerate(states[1:]):
            # The speed reference with preview: the profile where node j is expected.
            reference = {"vx_mps": par["speed_ref_mps"][j], "e1_m": 0.0, "e2_rad": 0.0}
            y = path_model.outputs(x_j)
            for name in path_model.OUTPUT_NAMES:
                cost += weight[name] * (y[path_model.OUTPUT[name]] - reference[name]) ** 2
        for i in range(n_c):
            cost += (cfg.weight_accel_increment * increments[INPUT["accel_mps2"], i] ** 2
                     + cfg.weight_steer_increment * increments[INPUT["steer_rad"], i] ** 2)
        for eps in slack.values():
            cost += cfg.weight_slack * (ca.sumsqr(eps) + ca.sum1(eps))

        blocks = {"inputs": ca.vertcat(*moved)}
        limits = {
            "e1_m": (-cfg.max_lateral_error_m, cfg.max_lateral_error_m),
            "e2_rad": (-cfg.max_heading_error_rad, cfg.max_heading_error_rad),
            "vx_mps": (cfg.min_speed_mps, cfg.max_speed_mps),
        }
        low_g = {"inputs": np.tile(self._input_low, n_c)}
        high_g = {"inputs": np.tile(self._input_high, n_c)}
        for name in SOFT_LIMIT_NAMES:
            values = ca.vertcat(*(x_j[state[name]] for x_j in states[1:]))
            low, high = limits[name]
            blocks[f"{name}_upper"] = values - slack[name]  # <= high
            low_g[f"{name}_upper"] = np.full(n_p, -np.inf)
            high_g[f"{name}_upper"] = np.full(n_p, high)
            blocks[f"{name}_lower"] = values + slack[name]  # >= low
            low_g[f"{name}_lower"] = np.full(n_p, low)
            high_g[f"{name}_lower"] = np.full(n_p, np.inf)
        g = ca.vertcat(*(blocks[name] for name in constraints.slices))

        name = TRACKER_NAME.replace("-", "_")
        options: dict[str, object] = {"error_on_fail": False}
        options.update(_BACKENDS[cfg.qp_solver].options(cfg.max_iterations))
        solver = ca.qpsol(name, cfg.qp_solver, {"x": z, "p": p, "f": cost, "g": g}, options)
        trajectory = ca.Function(f"{name}_trajectory", [z, p],
                                 [ca.horzcat(*states).T, ca.horzcat(*inputs).T],
                                 ["z", "p"], ["states", "inputs"])
        return _Qp(solver, trajectory, variables, params, constraints,
                   constraints.pack(low_g), constraints.pack(high_g))

    # ------------------------------------------------------------------ public API

    def _accept_previous(self, previous: np.ndarray) -> np.ndarray:
        """Clipped into the bounds: the first increment is taken against it."""
        return np.clip(previous, self._input_low, self._input_high)

    def _forget(self) -> None:
        self._actuator: ActuatorBelief | None = None
        self._yaw_rate_ref: np.ndarray | None = None
        """The desired yaw rates of the step's stages (for a fallback's rollout)."""

    def _start(self, t_s: float, estimate: Estimate, reference: ReferencePath) -> Start:
        self._yaw_rate_ref = None
        return self._starting_point(t_s, estimate, reference)

    def _solve(self, t_s: float, start: StartingPoint,  # type: ignore[override]
               reference: ReferencePath) -> Solved:
        """The condensed QP from the starting point (its own :meth:`_start`)."""
        yaw_rate_ref, speed_ref, ackermann = self._horizon_references(reference, start)
        self._yaw_rate_ref = yaw_rate_ref
        params = self._qp.params.pack({
            "state0": start.state,
            "input_prev": self._previous_input,
            "speed_lin_mps": start.state[path_model.STATE["vx_mps"]],
            "yaw_rate_ref_radps": yaw_rate_ref,
            "speed_ref_mps": speed_ref,
            "ackermann_steer_rad": ackermann,
        })
        lbx, ubx = self._variable_bounds(t_s)
        began = time.perf_counter()
        z, cost = self._qp.call(0.0, params, lbx=lbx, ubx=ubx)
        solve_time_s = time.perf_counter() - began
        stats = self._qp.call.stats()
        status, iterations = self._status(stats)
        states, inputs = self._qp.plan(z, params)
        return Solved(states, inputs, cost, status, iterations,
                      bool(stats.get("success", False)), solve_time_s)

    # ------------------------------------------------------------------ starting point

    def _actuator_at(self, t_s: float) -> ActuatorBelief:
        """The actuator belief advanced to ``t_s`` through the commands applied meanwhile
        (exact first-order lags); at rest at the last command when there is none yet."""
        belief = self._actuator
        if belief is None:
            return ActuatorBelief(t_s, float(self._previous_input[INPUT["steer_rad"]]),
                                  float(self._previous_input[INPUT["accel_mps2"]]))
        angle, accel = belief.road_wheel_angle_rad, belief.accel_mps2
        for duration_s, applied in self._issued.segments(belief.t_s, t_s):
            angle = float(steered.road_wheel_angle(
                angle, applied[INPUT["steer_rad"]], duration_s,
                self._steered.steer_time_constant_s))
            accel = self._lagged_accel(accel, applied[INPUT["accel_mps2"]], duration_s)
        return ActuatorBelief(max(t_s, belief.t_s), angle, accel)

    def _lagged_accel(self, accel_mps2: float, command_mps2: float, duration_s: float) -> float:
        """(P4) solved exactly over ``duration_s`` with the command held."""
        decay = math.exp(-duration_s / self._params.accel_time_constant_s)
        return float(command_mps2 + (accel_mps2 - command_mps2) * decay)

    def _starting_point(self, t_s: float, estimate: Estimate,
                        reference: ReferencePath) -> StartingPoint:
        """The estimate predicted to ``t_s`` plus the latency, in path coordinates (the
        latency prediction in the world frame, then the projection onto the path)."""
        missing = [name for name in ESTIMATED_STATE_NAMES if name not in estimate]
        if missing:
            raise ConfigError(f"tracker {TRACKER_NAME}: the estimate has no "
                              f"{', '.join(missing)}: expected an estimator that reports them")
        world = np.array([estimate[name] for name in ESTIMATED_STATE_NAMES])
        end_t_s = max(t_s, estimate.t_s) + self._issued.delay_s
        if not math.isfinite(end_t_s):
            return StartingPoint(t_s, np.full(len(path_model.STATE_NAMES), np.nan), s_m=math.nan)
        actuator = self._actuator = self._actuator_at(estimate.t_s)
        self._issued.forget_before(actuator.t_s)
        state = np.concatenate((world, [actuator.road_wheel_angle_rad]))
        accel = actuator.accel_mps2
        if np.all(np.isfinite(state)):
            for duration_s, applied in self._issued.segments(estimate.t_s, end_t_s):
                pieces = max(1, math.ceil(duration_s / _MAX_PREDICTION_PIECE_S - 1e-9))
                for _ in range(pieces):
                    state = np.asarray(self._predict_world(state, applied, duration_s / pieces),
                                       dtype=float).ravel()
                accel = self._lagged_accel(accel, applied[INPUT["accel_mps2"]], duration_s)
        world_index = steered.STATE
        values = {name: state[world_index[name]] for name in ("vy_mps", "yaw_rate_radps",
                                                               "vx_mps")}
        values["ax_mps2"] = accel
        s_m = math.nan
        if np.all(np.isfinite(state)):
            projection: Projection = reference.project(state[world_index["x_m"]],
                                                       state[world_index["y_m"]])
            s_m = projection.s_m
            values["e1_m"] = projection.lateral_error_m
            values["e2_rad"] = float(wrap_angle(state[world_index["yaw_rad"]]
                                                - projection.path_yaw_rad))
        else:
            values["e1_m"] = values["e2_rad"] = math.nan
        path_state = np.array([values[name] for name in path_model.STATE_NAMES], dtype=float)
        return StartingPoint(end_t_s, path_state, s_m=s_m)

    def _horizon_references(self, reference: ReferencePath,
                            start: StartingPoint
                            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``psi_D' = v kappa(s)`` (P7) at the middle of every stage, the speed reference at
        every node 1..Np (preview: the profile where and when the car is expected there, so
        it brakes on time for a bend ahead) and the path's Ackermann angle ``atan(L
        kappa(s))`` at the middle of every stage; ``s`` the arc length the car is expected
        to reach at the speeds ``v`` it is expected to drive. Before the first projection
        the speed reference is the top speed."""
        n, ts = self._n_p, self._ts
        times = start.t_s + 0.5 * ts * np.arange(2 * n + 1)  # stage boundaries and middles
        speed0 = start.state[path_model.STATE["vx_mps"]]
        speeds = np.full(times.size, speed0)
        last = self._last_good
        if last is not None and np.all(np.isfinite(last.states)):
            plan_times = last.start_t_s + ts * np.arange(self._n_p + 1)
            plan_speeds = last.states[:, path_model.STATE["vx_mps"]]
            speeds += np.interp(times, plan_times, plan_speeds) - np.interp(
                start.t_s, plan_times, plan_speeds)
        speeds = np.maximum(speeds, 0.0)
        s = start.s_m + np.concatenate(
            ([0.0], np.cumsum(0.5 * (speeds[:-1] + speeds[1:]) * 0.5 * ts)))
        middle, nodes = slice(1, None, 2), slice(2, None, 2)
        curvature = reference.sample(s[middle])["curvature_1pm"]
        if math.isfinite(start.s_m):
            speed_ref = reference.speed_ref(s[nodes], times[nodes])
        else:
            speed_ref = np.full(n, reference.speed_mps)
        ackermann = np.arctan(self.config.model.wheelbase_m * curvature)
        return speeds[middle] * curvature, np.asarray(speed_ref, dtype=float), ackermann

    # ------------------------------------------------------------------ helpers

    def _status(self, stats: Mapping[str, object]) -> tuple[str, int]:
        """The back-end's return status as text and its iteration count (0: not reported)."""
        backend = _BACKENDS[self.settings.qp_solver]
        status = stats.get("return_status", "unknown")
        if isinstance(status, int):
            status = backend.status_names.get(status, str(status))
        key = backend.iterations_key
        return str(status), int(stats.get(key, 0)) if key is not None else 0

    def _variable_bounds(self, t_s: float) -> tuple[np.ndarray, np.ndarray]:
        """Steering increments within the rate bound over the time each spans;
        acceleration increments free; slacks non-negative."""
        rate = self.config.max_steer_rate_radps
        spans = np.concatenate(([self._first_period_s(t_s)], np.full(self._n_c - 1, self._ts)))
        high_increments = np.empty((self._n_c, len(INPUT_NAMES)))
        high_increments[:, INPUT["accel_mps2"]] = np.inf
        high_increments[:, INPUT["steer_rad"]] = rate * spans
        n_slacks = len(SOFT_LIMIT_NAMES) * self._n_p
        low = {"increments": -high_increments.ravel(), "slacks": np.zeros(n_slacks)}
        high = {"increments": high_increments.ravel(), "slacks": np.full(n_slacks, np.inf)}
        return self._qp.variables.pack(low), self._qp.variables.pack(high)

    def _rollout(self, start: Start, inputs: np.ndarray) -> np.ndarray:
        """The path model driven by ``inputs`` from the starting point (NaN without this
        step's desired yaw rates)."""
        states = np.full((self._n_p + 1, len(path_model.STATE_NAMES)), np.nan)
        yaw_rate_ref = self._yaw_rate_ref
        if yaw_rate_ref is None:
            return states
        speed = start.state[path_model.STATE["vx_mps"]]
        states[0] = start.state
        for k, u in enumerate(inputs):
            states[k + 1] = np.asarray(self._step_model(states[k], u, speed, yaw_rate_ref[k]),
                                       dtype=float).ravel()
        return states

    def _plan_states(self, trajectory: Trajectory,
                     start: Start) -> tuple[tuple[str, ...], np.ndarray]:
        """The path-model states plus the world positions they stand for
        (:meth:`_world_positions`), so that views can draw the plan like any other."""
        s0_m = start.s_m if isinstance(start, StartingPoint) else math.nan
        return ((*self.state_names, *PLAN_WORLD_NAMES),
                np.column_stack((trajectory.states, self._world_positions(trajectory, s0_m))))

    def _world_positions(self, trajectory: Trajectory, s0_m: float) -> np.ndarray:
        """``[x_m, y_m]`` of every node: the path point at the arc length the node is
        expected to reach (``s0`` plus the trapezoid of ``vx Ts``, the small-angle (P5)-(P6)
        reading of ``s'``), moved by ``e1`` along the path's left normal. NaN without a path
        or a starting arc length."""
        states = trajectory.states
        if self._path is None or not math.isfinite(s0_m):
            return np.full((states.shape[0], len(PLAN_WORLD_NAMES)), np.nan)
        speed = np.maximum(states[:, path_model.STATE["vx_mps"]], 0.0)
        s = s0_m + np.concatenate(([0.0], np.cumsum(0.5 * (speed[:-1] + speed[1:]) * self._ts)))
        path = self._path.sample(s)
        e1 = states[:, path_model.STATE["e1_m"]]
        return np.column_stack((path["x_m"] - e1 * np.sin(path["yaw_rad"]),
                                path["y_m"] + e1 * np.cos(path["yaw_rad"])))
