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

Nothing depends on wall-clock time except the reported ``solve_time_s``, so equal inputs
give equal outputs.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np

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
from tracker.mpc.nmpc_model import NmpcModel
from tracker.mpc.nmpc_problem import NmpcProblem
from tracker.paths.reference_path import ReferencePath

__all__ = ["INPUT_NAMES", "Nmpc", "NmpcModel"]

_TIME_EPS_S = 1e-9
"""Slack when comparing simulated times, against float round-off of sums of periods."""


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
        self._n = config.horizon
        self._problem = NmpcProblem(config, model)
        self._params = self._problem.params
        self._nlp = self._problem.build()
        latency_s = config.latency_s if config.latency_compensation else 0.0
        self._issued = IssuedInputs(latency_s + model.unmodelled_lag_s,
                                    np.zeros(len(INPUT_NAMES)))
        self._failures = FailureClock(config.fallback_time_s)
        self._curvature: CurvatureTable | None = None
        self.reset()

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
        low, high = self._problem.input_bounds()
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
