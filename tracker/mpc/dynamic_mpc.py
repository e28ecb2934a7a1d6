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
   ``u_k = u_{k-1} + Delta u_k`` for ``k < Nc`` (``u_{-1}`` the command issued last), the
   input held from ``Nc`` on; the predicted states are affine in them (a condensed QP of
   ``2 Nc`` increments and ``3 Np`` slacks: 34 variables by default). Cost
   (:mod:`tracker.mpc.dynamic_mpc_config`)::

       J = sum_{j=1..Np} ||Y_j - Y_ref||_Q^2 + sum_{i<Nc} ||Delta u_i||_R^2 + slack terms

   with ``Y = [vx, e1, e2]``, ``Y_ref = [v_D,j, 0, 0]``: ``v_D,j`` the speed profile where
   and when node ``j`` is expected (preview: the reference design holds one ``v_D``, which
   lags a braking profile by the whole horizon). Hard bounds: steering within
   ``min(tracker.max_steer_rad, dynamic_mpc.max_steer_rad)`` (reference design: 15 deg),
   acceleration within ``[tracker.accel_min_mps2, tracker.accel_max_mps2]`` (reference design:
   +-3 m/s^2), steering increments within ``max_steer_rate_radps`` times the time they
   span (the time since the last command for the first). Soft limits (the reference design's hard
   ones, softened so the QP is never infeasible): ``|e1| <= 0.5 m``, ``|e2| <= 3 deg``,
   ``0 <= vx <= 30 m/s``, with one slack per limit and node ``1..Np``, penalised squared
   and linearly with ``weight_slack``. The QP is one ``ca.qpsol`` built in the
   constructor with every step-dependent number (starting state, previous input, ``v0``,
   the desired yaw rates, the ``v_D,j``) as a parameter: a step only evaluates it.
4. **Failures** (:mod:`tracker.mpc.fallback`): a failed QP, an exception or a non-finite
   result never raises: the last good plan is replayed, shifted by the elapsed time
   (status ``fallback (...)``), then after ``tracker.fallback_time_s`` a safe stop
   (``safe_stop (...)``); ``success=False, fallback=True``.

The plan's states are the path-model states at nodes ``0..Np`` (node 0 is the predicted
starting point, at ``t_s`` plus the latency), its inputs the commands of the ``Np``
stages; ``dt_s`` is ``Ts``. Nothing depends on wall-clock time but ``solve_time_s``.

Choices, and the measurements behind them (MuJoCo sedan with Pacejka tyres, EKF in the
loop, ``lane-change``: the stretched double lane change at 20 m/s from 15 m/s, 0.5 g;
max CTE for seeds 0-4; on its own model, the bench of the tests, 64 mm against the
reference design's 88 mm):

* **Back-end: HiGHS** (``qp_solver: highs``; its active-set QP solver reports its
  iterations, about 39 per step: it counts every slack bound it fixes). On 4500 QPs
  logged from 15 plant runs (seeds 0-4: nominal, 100 ms delay uncompensated, the reference design's
  belief) HiGHS failed once ("claims optimality, but with primal infeasibilities" of
  1e-4; the fallback replays the last plan for that step), 0.8 ms median. DAQP (``daqp``)
  solved all of them in 0.27 ms with the same solutions (within 5e-9) but reports no
  iteration count through CasADi (logged as 0). qrqp, CasADi's own, failed 349 (cycling,
  "Failed to calculate search direction"); OSQP failed 1-3 and reports no iterations;
  qpOASES solves them but prints its licence banner to stdout at every call; HPIPM needs
  the multiple-shooting structure, not a condensed QP.
* **A slack per node**, not one per limit over the horizon (the worst violation): the
  same on the lane change, but from 2 m off the path one slack lets every later node
  violate as much as the first, which nothing can change, and the car overshoots by
  0.48 m instead of 0.15 m (the tests' bench). 34 variables instead of 7 cost 0.14 ms.
  Without the soft limits (``weight_slack = 0``) the lane change is within 7 mm of the
  same (the 3 deg heading limit is reached in 8 of 300 plans, seed 0); with the earlier
  ``weight_heading = 10`` it was 0.057-0.084 m instead of 0.047-0.055 m: the limit then
  bound during the swings and damped them.
* **Weights.** What matters is ``weight_lateral / weight_steer_increment`` (the scale at
  a fixed ratio changes nothing: 100/2000, 300/6000, 1000/20000 give the same to 0.2 mm);
  max CTE over the seeds for the ratio 1 / 0.1 / 0.05 / 0.04 / 0.01 (heading 10):
  0.089 / 0.065 / 0.055 / 0.061 / 0.157 m. Then ``weight_heading`` 10 / 300 / 1000 at
  the ratio 0.04: 0.061 / 0.054 / 0.051 m (at 0.05, 10 / 300 / 1000 / 3000: 0.055 /
  0.053 / 0.056 / 0.069 m). ``weight_accel_increment``
  ramps the acceleration up over 0.15 s instead of stepping to 3 m/s^2: with 0.1 the
  rear-driven sedan on ``plant.tire_friction=0.7`` spins its wheels at the step, keeps
  accelerating into the lane change and spins out (13-14 m); with 10 it tracks within
  0.048 m. The reference design reaches 18.3 m/s at 1.1 s, this 18.2 m/s.
* **The reference design's heading reference** ``e2 = 0``. In a steady turn the heading differs from
  the path's by the side slip, so the heading weight buys it with a small lateral offset
  (the bench: 8 mm in a steady 0.5 g turn, 0.1 mm with ``weight_heading = 10``). A
  reference of minus the belief's steady side slip (S3) removes it, but did not help the
  lane change (0.050 m at best, heading weight 300), so the reference design's is kept.
* **No actuator lag in the model** (the reference design's): also predicting over the belief's
  steering time constant, as :mod:`tracker.mpc.kinematic_nmpc` does, made it worse (with
  earlier weights: 0.068 m with 25 ms more, 0.086 m with 50 ms, against 0.055 m). On
  the bench the lag even helps: 84 mm without it (``Nc = 5``: 52 mm).

Measured with the defaults: max CTE [m] for seeds 0 / 1 / 2 / 3 / 4, and the solve time
[ms], the range over the seeds of the median / of the 99th percentile (two cores shared
with other work)::

    run                                  max CTE [m], seeds 0-4              solve [ms]
    defaults                             0.032 0.049 0.050 0.043 0.044   0.95-1.07 / 1.2-1.8
    plant.actuator_delay_s=0.1           0.027 0.049 0.043 0.052 0.054   0.93-1.05 / 1.1-1.6
      tracker.latency_compensation=false 0.082 0.154 0.123 0.093 0.102   1.02-1.12 / 1.3-1.9
    qp_solver=daqp                       identical                       0.37-0.46 / 0.45-0.80
    control_horizon=5                    0.026 0.046 0.053 0.044 0.044   1.27-1.48 / 1.6-2.6
    belief C_f 19000, C_r 33000 N/rad    0.562 0.586 0.559 0.553 0.574  0.81-0.86 / 1.1-1.3

No solver failures in these 30 runs; HiGHS takes 39 iterations median (at most 54).
Max heading error 0.030-0.032 rad (the reference design: < 3 deg = 0.052), max steering
0.066-0.070 rad. The reference design's belief (C_f 19000, C_r 33000 N/rad) expects 3.8 /
2.4 times softer tyres than the sedan's (15 deg/g of understeer against 2.2) and a side
slip of 4.6 deg at 0.5 g, beyond its own 3 deg heading limit. Other cases:
``plant.mass_kg=2000`` 0.076 / 0.063 / 0.062 m (seeds 0-2), ``plant.tire_friction=0.7``
0.042 / 0.048 / 0.046 m; the model has no tyre limits (unlike ``dynamic-nmpc``'s soft
slip-angle limits), yet Falcone's unstretched path
(``lane-change-limit``, 1.11 g) ends at 0.44 / 0.48 m (seeds 0 / 1), held by the 15 deg
steering bound and the heading limit; MuJoCo contact tyres (``plant.tire_model=contact``,
no cornering compliance at all) 0.54-0.67 m.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import casadi as ca
import numpy as np

from cosim.core.exceptions import ConfigError
from cosim.core.records import Command, Estimate, Plan
from tracker.config import TrackerConfig
from tracker.models import path_error_bicycle as path_model
from tracker.models import steered_dynamic_bicycle as steered
from tracker.mpc.delay_line import IssuedInputs
from tracker.mpc.dynamic_mpc_config import DynamicMpcConfig
from tracker.mpc.fallback import INPUT, INPUT_NAMES, FailureClock, safe_stop_inputs, shifted_inputs
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
class StartingPoint:
    """Where the optimisation starts: the estimate predicted over its age and the latency."""

    t_s: float
    """Time the state is predicted to [s]."""
    state: np.ndarray
    """Path-model state (:data:`tracker.models.path_error_bicycle.STATE_NAMES`)."""
    s_m: float
    """Arc length of the predicted position's projection onto the path [m]."""


@dataclass(frozen=True)
class _Trajectory:
    """States (Np + 1 rows) and inputs (Np rows) of a plan made at ``t_s``, its node 0 at
    ``start_t_s``."""

    t_s: float
    start_t_s: float
    states: np.ndarray
    inputs: np.ndarray


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


class DynamicMpc:
    """Delta-u linear MPC on the path-error dynamic bicycle with a CasADi QP.

    Args:
      config: the tracker configuration; ``config.dynamic_mpc`` holds the horizons, the
        weights, the limits and the QP back-end; ``config.model`` is the belief (mass,
        yaw inertia, CoG position, axle cornering stiffnesses, steering time constant).
    """

    def __init__(self, config: TrackerConfig) -> None:
        if config.name != TRACKER_NAME:
            raise ConfigError(f"name = {config.name!r}: DynamicMpc expects {TRACKER_NAME!r}")
        self.config = config
        self.settings: DynamicMpcConfig = config.dynamic_mpc
        self.state_names: tuple[str, ...] = path_model.STATE_NAMES
        self.input_names: tuple[str, ...] = INPUT_NAMES
        self._n_p = self.settings.prediction_horizon
        self._n_c = self.settings.control_horizon
        self._ts = self.settings.sample_time_s
        self._params = path_model.PathErrorParams.from_vehicle(
            config.model, self.settings.accel_time_constant_s)
        self._steered = steered.SteeredBicycleParams.from_vehicle(config.model)
        self._step_model = path_model.discrete_function(self._params, self._ts)
        self._predict_world = steered.predict_function(self._steered)
        self._input_low = np.empty(len(INPUT_NAMES))
        self._input_high = np.empty(len(INPUT_NAMES))
        max_steer = min(config.max_steer_rad, self.settings.max_steer_rad)
        self._input_low[INPUT["accel_mps2"]] = config.accel_min_mps2
        self._input_high[INPUT["accel_mps2"]] = config.accel_max_mps2
        self._input_low[INPUT["steer_rad"]] = -max_steer
        self._input_high[INPUT["steer_rad"]] = max_steer
        self._qp = self._build_qp()
        self._issued = IssuedInputs(
            config.latency_s if config.latency_compensation else 0.0,
            np.zeros(len(INPUT_NAMES)),
        )
        self._clock = FailureClock(config.fallback_time_s)
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

        # Rollout: x_{k+1} = F(x_k, u_k; v0, psi_D'_k), u_k = u_{k-1} + Delta u_k (k < Nc).
        x, u = par["state0"], par["input_prev"]
        states, inputs, moved = [x], [], []
        for k in range(n_p):
            if k < n_c:
                u = u + increments[:, k]
                moved.append(u)
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

    def reset(self, previous_command: Command | None = None) -> None:
        """Forget every previous step.

        ``previous_command`` is the actuation already applied to the car (default: zero
        acceleration and steering, clipped into the bounds); the first increment is taken
        against it, and the actuators start at rest at it.
        """
        previous = np.zeros(len(INPUT_NAMES))
        if previous_command is not None:
            previous[INPUT["accel_mps2"]] = previous_command.accel_mps2
            previous[INPUT["steer_rad"]] = previous_command.steer_rad
        self._previous_input = np.clip(previous, self._input_low, self._input_high)
        self._previous_t_s: float | None = None
        self._issued.reset(self._previous_input)
        self._clock.reset()
        self._actuator: ActuatorBelief | None = None
        self._last_good: _Trajectory | None = None
        self._reference: ReferencePath | None = None
        """The path of the last step: the plan's world positions are laid along it."""
        self._last_speed_mps = math.nan

    def step(
        self, t_s: float, estimate: Estimate, reference: ReferencePath
    ) -> tuple[Command, Plan]:
        """One control step: the command to apply at ``t_s`` and the plan behind it."""
        start = self._starting_point(t_s, estimate, reference)
        self._reference = reference
        if not np.all(np.isfinite(start.state)):
            return self._fallback(t_s, start, None, "non_finite_estimate", 0, 0.0)
        yaw_rate_ref, speed_ref = self._horizon_references(reference, start)
        params = self._qp.params.pack({
            "state0": start.state,
            "input_prev": self._previous_input,
            "speed_lin_mps": start.state[path_model.STATE["vx_mps"]],
            "yaw_rate_ref_radps": yaw_rate_ref,
            "speed_ref_mps": speed_ref,
        })
        lbx, ubx = self._variable_bounds(t_s)
        began = time.perf_counter()
        try:
            solution = self._qp.solver(x0=np.zeros(self._qp.variables.size), p=params,
                                       lbx=lbx, ubx=ubx, lbg=self._qp.lbg, ubg=self._qp.ubg)
            solve_time_s = time.perf_counter() - began
            stats = self._qp.solver.stats()
            z = np.asarray(solution["x"], dtype=float).ravel()
            cost = float(solution["f"])
        except RuntimeError as error:  # a CasADi evaluation error: a failed solve
            solve_time_s = time.perf_counter() - began
            return self._fallback(t_s, start, yaw_rate_ref, f"error: {error}", 0,
                                  solve_time_s)
        status, iterations = self._status(stats)
        if not (stats.get("success", False) and np.all(np.isfinite(z)) and math.isfinite(cost)):
            return self._fallback(t_s, start, yaw_rate_ref, status, iterations, solve_time_s)
        states, inputs = (np.asarray(m, dtype=float) for m in self._qp.trajectory(z, params))
        trajectory = _Trajectory(t_s, start.t_s, states, self._clip(inputs))
        self._last_good = trajectory
        self._clock.reset()
        plan = self._plan(trajectory, cost, solve_time_s, iterations, status, True, False,
                          start.s_m)
        return self._commit(trajectory), plan

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
        """The estimate predicted to ``t_s`` plus the latency, in path coordinates."""
        missing = [name for name in ESTIMATED_STATE_NAMES if name not in estimate]
        if missing:
            raise ConfigError(f"tracker {TRACKER_NAME}: the estimate has no "
                              f"{', '.join(missing)}: expected an estimator that reports them")
        world = np.array([estimate[name] for name in ESTIMATED_STATE_NAMES])
        end_t_s = max(t_s, estimate.t_s) + self._issued.delay_s
        if not math.isfinite(end_t_s):
            return StartingPoint(t_s, np.full(len(path_model.STATE_NAMES), np.nan), math.nan)
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
            self._last_speed_mps = float(values["vx_mps"])
        else:
            values["e1_m"] = values["e2_rad"] = math.nan
        path_state = np.array([values[name] for name in path_model.STATE_NAMES], dtype=float)
        return StartingPoint(end_t_s, path_state, s_m)

    def _horizon_references(self, reference: ReferencePath,
                            start: StartingPoint) -> tuple[np.ndarray, np.ndarray]:
        """``psi_D' = v kappa(s)`` (P7) at the middle of every stage, and the speed
        reference at every node 1..Np (preview: the profile where and when the car is
        expected there, so it brakes on time for a bend ahead); ``s`` the arc length the car
        is expected to reach at the speeds ``v`` it is expected to drive. Before the first
        projection the speed reference is the top speed."""
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
        return speeds[middle] * curvature, np.asarray(speed_ref, dtype=float)

    # ------------------------------------------------------------------ helpers

    def _status(self, stats: Mapping[str, object]) -> tuple[str, int]:
        """The back-end's return status as text and its iteration count (0: not reported)."""
        backend = _BACKENDS[self.settings.qp_solver]
        status = stats.get("return_status", "unknown")
        if isinstance(status, int):
            status = backend.status_names.get(status, str(status))
        key = backend.iterations_key
        return str(status), int(stats.get(key, 0)) if key is not None else 0

    def _first_period_s(self, t_s: float) -> float:
        """Time since the last command; on the first step ``min(tracker.dt_s, Ts)``."""
        if self._previous_t_s is None:
            return min(self.config.dt_s, self._ts)
        return max(t_s - self._previous_t_s, 0.0)

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

    def _clip(self, inputs: np.ndarray) -> np.ndarray:
        """The QP may end a hair outside a bound; the command never does."""
        return np.clip(inputs, self._input_low, self._input_high)

    def _rollout(self, start: StartingPoint, yaw_rate_ref: np.ndarray | None,
                 inputs: np.ndarray) -> np.ndarray:
        """The path model driven by ``inputs`` from the starting point (NaN if unknown)."""
        states = np.full((self._n_p + 1, len(path_model.STATE_NAMES)), np.nan)
        if yaw_rate_ref is None or not np.all(np.isfinite(start.state)):
            return states
        speed = start.state[path_model.STATE["vx_mps"]]
        states[0] = start.state
        for k, u in enumerate(inputs):
            states[k + 1] = np.asarray(self._step_model(states[k], u, speed, yaw_rate_ref[k]),
                                       dtype=float).ravel()
        return states

    def _commit(self, trajectory: _Trajectory) -> Command:
        """Issue the trajectory's first input."""
        first = trajectory.inputs[0].copy()
        self._previous_input = first
        self._previous_t_s = trajectory.t_s
        self._issued.record(trajectory.t_s, first)
        return Command(t_s=trajectory.t_s, accel_mps2=float(first[INPUT["accel_mps2"]]),
                       steer_rad=float(first[INPUT["steer_rad"]]))

    def _fallback(self, t_s: float, start: StartingPoint, yaw_rate_ref: np.ndarray | None,
                  status: str, iterations: int, solve_time_s: float) -> tuple[Command, Plan]:
        """Replay the last good plan shifted; after ``fallback_time_s``, a safe stop."""
        if self._clock.fail(t_s):
            inputs = safe_stop_inputs(
                self._n_p, self._ts, self._first_period_s(t_s),
                float(self._previous_input[INPUT["steer_rad"]]), self._safe_stop_speed_mps(),
                self.config.max_steer_rate_radps, self.config.safe_stop_accel_mps2)
            status = f"safe_stop ({status})"
        elif self._last_good is not None:
            inputs = shifted_inputs(self._last_good.inputs, self._last_good.t_s, t_s, self._ts)
            status = f"fallback ({status})"
        else:
            inputs = np.tile(self._previous_input, (self._n_p, 1))
            status = f"fallback ({status})"
        inputs = self._clip(inputs)
        trajectory = _Trajectory(t_s, start.t_s, self._rollout(start, yaw_rate_ref, inputs),
                                 inputs)
        plan = self._plan(trajectory, math.nan, solve_time_s, iterations, status, False, True,
                          start.s_m)
        return self._commit(trajectory), plan

    def _world_positions(self, trajectory: _Trajectory, s0_m: float) -> np.ndarray:
        """``[x_m, y_m]`` of every node: the path point at the arc length the node is
        expected to reach (``s0`` plus the trapezoid of ``vx Ts``, the small-angle (P5)-(P6)
        reading of ``s'``), moved by ``e1`` along the path's left normal. NaN without a path
        or a starting arc length."""
        states = trajectory.states
        if self._reference is None or not math.isfinite(s0_m):
            return np.full((states.shape[0], len(PLAN_WORLD_NAMES)), np.nan)
        speed = np.maximum(states[:, path_model.STATE["vx_mps"]], 0.0)
        s = s0_m + np.concatenate(([0.0], np.cumsum(0.5 * (speed[:-1] + speed[1:]) * self._ts)))
        path = self._reference.sample(s)
        e1 = states[:, path_model.STATE["e1_m"]]
        return np.column_stack((path["x_m"] - e1 * np.sin(path["yaw_rad"]),
                                path["y_m"] + e1 * np.cos(path["yaw_rad"])))

    def _safe_stop_speed_mps(self) -> float:
        """The speed a safe stop brakes from: the last finite starting speed, else (never
        known) the fastest the tracker plans for, so that it brakes over the whole horizon."""
        if math.isfinite(self._last_speed_mps):
            return self._last_speed_mps
        return self.settings.max_speed_mps

    def _plan(self, trajectory: _Trajectory, cost: float, solve_time_s: float,
              iterations: int, status: str, success: bool, fallback: bool,
              s0_m: float) -> Plan:
        """The plan: the path-model states plus the world positions they stand for
        (:meth:`_world_positions`), so that views can draw it like any other plan."""
        return Plan(
            t_s=trajectory.t_s,
            dt_s=self._ts,
            state_names=(*self.state_names, *PLAN_WORLD_NAMES),
            states=np.column_stack((trajectory.states, self._world_positions(trajectory, s0_m))),
            input_names=self.input_names,
            inputs=trajectory.inputs.copy(),
            cost=cost,
            solve_time_s=solve_time_s,
            iterations=iterations,
            status=status,
            success=success,
            fallback=fallback,
        )
