"""Linear time-varying MPC on the steered dynamic bicycle, one QP per step.

Falcone, Borrelli, Asgari, Tseng, Hrovat ("Predictive active steering control for
autonomous vehicle systems", IEEE TCST 15(3), 2007, sec. IV) linearise the vehicle model
about a trajectory, subtract it and solve the resulting linear time-varying MPC as a QP
(so do Lages and Alves, "Real-time control of a mobile robot using linearized model
predictive control", IFAC 2006, about the reference trajectory). This tracker does the job of
``dynamic-nmpc`` (:mod:`tracker.mpc.nmpc` on :mod:`tracker.models.steered_dynamic_bicycle`)
that way: the same model (the linear-tyre dynamic bicycle of Rajamani 2012, sec. 2.3, with the
steering actuator as a state), the same cost and reference, the same bounds, latency
handling, fallback and plan; only the solver differs. The QP and the linearisation are
:mod:`tracker.mpc.ltv_qp`.

Per step:

1. **Initial state** (as :mod:`tracker.mpc.nmpc`): the estimate's six vehicle states by name;
   the road-wheel angle, which no estimator reports, is an internal state: last step's
   angle propagated through the commands the car has applied since (exact for the lag
   (A2) the actuator is). The state is then predicted from ``estimate.t_s`` to
   ``max(t_s, estimate.t_s) + latency_s`` (latency compensation; ``latency_s``
   only with ``latency_compensation``) piece by piece through the commands in the delay
   line (:class:`tracker.mpc.delay_line.IssuedInputs`): the estimate's age and the transport
   delay, each with the input the car actually applies then.
2. **Warm start**: the previous plan shifted by the elapsed time (its tail extended
   through the model), node 0 replaced by the initial state; on the first step the last
   applied input held over the horizon and rolled out through the model.
3. **Reference** (as :mod:`tracker.mpc.nmpc`): the initial state's projection on the path;
   reference points at the arc lengths the warm start expects to cover,
   ``s_k = s_0 + sum_j (v_j + v_{j+1}) dt / 2``; the path yaw unwrapped along the horizon
   and shifted by whole turns to within pi of the car's yaw; the reference speed.
4. **Linearisation trajectory** ``(xbar, ubar)``, ``tracker.ltv_mpc.linearise_about``:

   * ``previous-plan`` (default): the warm start itself, the real-time-iteration scheme
     (one SQP iteration per step, the previous solution as the linearisation point). Its
     defects ``c_k`` (L3) are the previous solution's error against the nonlinear model.
   * ``reference``: the reference trajectory ``(X_r, U_r)`` of Lages and Alves 2006. Nodes 1..N sit
   on the reference
     points with the path yaw and the warm start's speeds, in the steady turn of the
     path's curvature ``kappa`` (:mod:`tracker.models.dynamic_bicycle`, (S1)-(S3))::

         r = v kappa,   delta = kappa (L + K v^2),   vy = r (l_r - m l_f v^2 / (L C_r))

     the road-wheel angle and the steering input at ``delta``, the acceleration from
     the speeds. Node 0 is the initial state in both modes: it is known exactly, so
     linearising about anything else would only add error.

5. **QP** (:class:`tracker.mpc.ltv_qp.LtvQp`): the NMPC's cost, bounds and soft slip-angle
   limits (``tracker.ltv_mpc.slip_limits``) on the LTV model, one solve. The first input
   is applied (clipped onto the bounds and the steering-rate limit against the previous
   command, which removes the back-end's round-off); the solution is the next warm
   start.

Failures (:mod:`tracker.mpc.base`, the skeleton every MPC shares): a non-finite initial
state, a back-end failure, a numerical error anywhere in steps 1-5 or a non-finite
solution never raise: the last good plan is replayed, shifted (``fallback (...)``), and
once failures have lasted longer than ``fallback_time_s`` a safe stop is commanded
(``safe_stop (...)``); ``success=False``, ``fallback=True``. A success ends either.

The plan's ``solve_time_s`` is the QP back-end's call alone (what the runner's
``solve_ms`` reports); the linearisation and the rest of the step are in
:attr:`LtvMpc.timing`. Nothing depends on wall-clock time except those timings, so equal
inputs give equal outputs.

The measurements behind the defaults (back-end, linearisation trajectory, slip limits):
docs/defaults.md, ``ltv-mpc``; today's accuracy: ``docs/trackers.md``.
"""

from __future__ import annotations

import time
from types import MappingProxyType

import numpy as np

from cosim.core.exceptions import ConfigError
from tracker.config import TrackerConfig
from tracker.models import dynamic_bicycle as bicycle
from tracker.models import steered_dynamic_bicycle as steered
from tracker.models.steered_dynamic_bicycle import STATE, STATE_NAMES
from tracker.mpc.base import Solved, Start, Trajectory
from tracker.mpc.fallback import INPUT, INPUT_NAMES
from tracker.mpc.horizon_reference import horizon_reference
from tracker.mpc.ltv_qp import REFERENCE_NAMES, Linearisation, LtvQp, QpProblem
from tracker.mpc.starting_state import EstimatedStartMpc
from tracker.paths.reference_path import ReferencePath

TRACKER_NAME = "ltv-mpc"
"""``tracker.name`` of this tracker."""

INTERNAL_STATE_REST_INPUTS = MappingProxyType({"road_wheel_angle_rad": "steer_rad"})
"""The model's states no estimator reports, and the input each one rests at."""


class LtvMpc(EstimatedStartMpc):
    """LTV-MPC path tracker: the steered dynamic bicycle linearised, one QP per step.

    Args:
      config: the tracker configuration; ``config.ltv_mpc`` picks the QP back-end, the
        formulation and the linearisation trajectory; ``config.model`` is the belief
        (as for ``dynamic-nmpc``).

    The estimate must hold ``x_m, y_m, yaw_rad, vx_mps, vy_mps, yaw_rate_radps``. The
    plan's states are :data:`tracker.models.steered_dynamic_bicycle.STATE_NAMES` as the LTV
    model predicts them; node 0 is the initial state (the car at ``t_s + latency``); the
    plan's and the command's ``t_s`` are the time of the step. :attr:`timing` splits the
    step's wall time into the linearisation (``setup_s``), the QP and the rest.
    """

    state_names: tuple[str, ...] = STATE_NAMES

    def __init__(self, config: TrackerConfig) -> None:
        if config.name != TRACKER_NAME:
            raise ConfigError(f"name = {config.name!r}: LtvMpc expects {TRACKER_NAME!r}")
        params = steered.SteeredBicycleParams.from_vehicle(config.model)
        self._bicycle = params.bicycle
        self._step_function = steered.discrete_function(params, config.dt_s)
        self._rollout_function = self._step_function.mapaccum(config.horizon)
        slip_limits = config.ltv_mpc.slip_limits
        self._linearisation = Linearisation(
            self._step_function, config.horizon,
            steered.slip_angle_function(params) if slip_limits else None)
        self._qp = LtvQp(config, STATE_NAMES, self._linearisation,
                         steered.linear_range_slip_rad(params, config.model.tyre_friction)
                         if slip_limits else ())
        latency_s = config.latency_s if config.latency_compensation else 0.0
        super().__init__(config, config.dt_s, config.horizon, self._qp.input_low,
                         self._qp.input_high, STATE["vx_mps"], latency_s)
        self._init_start(f"tracker {TRACKER_NAME}", STATE_NAMES, steered.VEHICLE_STATE_NAMES,
                         INTERNAL_STATE_REST_INPUTS, steered.predict_function(params))
        self.reset()

    # ------------------------------------------------------------------ the step

    def _solve(self, t_s: float, start: Start, reference: ReferencePath) -> Solved:
        state0 = start.state
        warm = self._warm_start(t_s, state0, self._step_function, STATE["yaw_rad"])
        ref = self._reference(reference, state0, warm.states, t_s)
        bar = (warm if self.config.ltv_mpc.linearise_about == "previous-plan"
               else self._reference_trajectory(t_s, state0, warm, ref))
        lin_start = time.perf_counter()
        linearisation = self._linearisation(bar.states, bar.inputs)
        linearise_s = time.perf_counter() - lin_start
        result = self._qp.solve(QpProblem(
            state_bar=bar.states, input_bar=bar.inputs, linearisation=linearisation,
            state0=state0, input_prev=self._previous_input,
            reference={name: ref[name] for name in REFERENCE_NAMES},
            steer_rate_weight=float(self.config.weights.steer_rate) * start.caution,
        ))
        return Solved(result.states, result.inputs, result.cost, result.status,
                      result.iterations, result.success, result.solve_time_s,
                      setup_s=linearise_s)

    def _rollout(self, start: Start, inputs: np.ndarray) -> np.ndarray:
        """``state0`` and the model's states under ``inputs`` (N rows): N+1 rows."""
        states = np.asarray(self._rollout_function(start.state, inputs.T), dtype=float).T
        return np.vstack((start.state, states))

    def _reference(self, reference: ReferencePath, state0: np.ndarray,
                   warm_states: np.ndarray, t_s: float) -> dict[str, np.ndarray]:
        """Reference points at the arc lengths the warm start expects to cover
        (:mod:`tracker.mpc.horizon_reference`, ``tracker.reference``), with the reference's
        curvature there (``curvature_1pm``) and the speed profile at each stage."""
        points = horizon_reference(self.config.reference, reference, state0[STATE["x_m"]],
                                   state0[STATE["y_m"]], state0[STATE["yaw_rad"]],
                                   warm_states[:, STATE["vx_mps"]], self.config.dt_s)
        return {
            "ref_x_m": points.x_m,
            "ref_y_m": points.y_m,
            "ref_yaw_rad": points.yaw_rad,
            "ref_speed_mps": points.speed_mps(reference, t_s, self.config.dt_s),
            "curvature_1pm": points.curvature_1pm,
        }

    def _reference_trajectory(self, t_s: float, state0: np.ndarray, warm: Trajectory,
                              ref: dict[str, np.ndarray]) -> Trajectory:
        """The reference trajectory ``(X_r, U_r)``: the reference points in the steady turn of
        the path's curvature at the warm start's speeds (module docstring, item 4)."""
        b = self._bicycle
        speed = warm.states[1:, STATE["vx_mps"]]
        curvature = ref["curvature_1pm"]
        yaw_rate = speed * curvature
        steer = curvature * (b.wheelbase_m + b.understeer_gradient_radpmps2 * speed**2)  # (S2)
        states = np.empty((self._n + 1, len(STATE_NAMES)))
        states[0] = state0
        nodes = {
            "x_m": ref["ref_x_m"], "y_m": ref["ref_y_m"], "yaw_rad": ref["ref_yaw_rad"],
            "vx_mps": speed,
            "vy_mps": np.asarray(bicycle.steady_lateral_velocity(speed, yaw_rate,
                                                                 b.as_vector())),  # (S3)
            "yaw_rate_radps": yaw_rate, "road_wheel_angle_rad": steer,
        }
        for name, values in nodes.items():
            states[1:, STATE[name]] = values
        inputs = np.empty((self._n, len(INPUT_NAMES)))
        inputs[:, INPUT["steer_rad"]] = np.clip(steer, -self.config.max_steer_rad,
                                                self.config.max_steer_rad)
        inputs[:, INPUT["accel_mps2"]] = np.clip(
            np.diff(warm.states[:, STATE["vx_mps"]]) / self.config.dt_s,
            self.config.accel_min_mps2, self.config.accel_max_mps2)
        return Trajectory(t_s, t_s, states, inputs)

    # ------------------------------------------------------------------ outputs

    def _clip_solution(self, inputs: np.ndarray) -> np.ndarray:
        """The QP's inputs exactly within the bounds and the steering-rate limit (the
        back-ends meet them only to their tolerance)."""
        clipped = np.clip(inputs, self._qp.input_low, self._qp.input_high)
        steer = INPUT["steer_rad"]
        rate_step = self.config.max_steer_rate_radps * self.config.dt_s
        previous = self._previous_input[steer]
        for k in range(clipped.shape[0]):
            low = max(self._qp.input_low[steer], previous - rate_step)
            high = min(self._qp.input_high[steer], previous + rate_step)
            clipped[k, steer] = min(max(clipped[k, steer], low), high)
            previous = clipped[k, steer]
        return clipped
