"""Nonlinear MPC on the kinematic bicycle (seed digest section 1).

At every control step solve, by multiple shooting with IPOPT,
``min_{x,u} sum_k c_k(x_k, u_k)  s.t.  x_{k+1} = F(x_k, u_k), x_0 = estimated state``,
apply the first input and keep the rest as the next warm start.

* Model ``F``: the kinematic bicycle at the centre of gravity, RK4 over one stage
  (:mod:`tracker.kinematic_bicycle`).
* Reference: the estimate is projected onto the path; reference points are laid along it
  at the arc lengths the car is expected to cover, ``s_k = s_0 + sum v_j dt`` with ``v_j``
  the speeds of the warm start (the previous plan, or the current speed on the first step).
  This replaces the seed's cubic fit in the vehicle frame; the path is already a spline.
* Cost (section 1; the exact form is in :mod:`tracker.config`): cross-track error measured
  from each reference point's tangent, heading error (the path yaw is unwrapped along the
  horizon and shifted by whole turns to within pi of the current yaw, so the difference is
  smooth and needs no wrapping inside the NLP), speed error to ``reference.speed_mps``,
  acceleration and steering, and their rates; the first rate is taken against the
  previously applied command.
* Bounds: steering ``|delta| <= max_steer_rad`` (pi/8 in section 1), acceleration in
  ``[accel_min_mps2, accel_max_mps2]``, steering rate ``|delta_k - delta_{k-1}| <=
  max_steer_rate_radps dt``.
* Warm start: the previous solution shifted by the time elapsed; on the first step the
  last applied actuation held over the horizon and rolled out through the model (section
  1, "warm start").
* Latency (section 1, item (a)): the estimate is predicted forward over ``latency_s`` (plus
  the age of the estimate) with the previous command before the optimisation starts.
* Failures: the solver status is checked every step. On failure, or on a non-finite
  result, the last good plan is replayed, shifted by the elapsed time (``fallback=True``);
  once failures have lasted longer than ``fallback_time_s`` the tracker commands a safe
  stop: steering back to zero at the steering-rate limit, then held, and a constant
  deceleration to standstill. :meth:`KinematicNmpc.step` never raises for a solver failure.

The NLP is built once in the constructor; a step only sets parameters and solves. Nothing
depends on wall-clock time except the reported ``solve_time_s``, so equal inputs give
equal outputs.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

import casadi as ca
import numpy as np

from cosim.exceptions import ConfigError
from cosim.records import Command, Estimate, Plan
from tracker.config import TrackerConfig
from tracker.kinematic_bicycle import (
    INPUT,
    INPUT_NAMES,
    STATE,
    STATE_NAMES,
    discrete_function,
    predict_function,
)
from tracker.reference_path import ReferencePath

_ESTIMATE_NAMES: tuple[str, ...] = STATE_NAMES
"""The estimate's states this tracker reads; the model's state names are the same."""

_TIME_EPS_S = 1e-9
"""Slack when comparing simulated times, against float round-off of sums of periods."""


class _Layout:
    """Named blocks of a flat vector (parameters or constraints), in declaration order."""

    def __init__(self, sizes: tuple[tuple[str, int], ...]) -> None:
        slices: dict[str, slice] = {}
        start = 0
        for name, size in sizes:
            slices[name] = slice(start, start + size)
            start += size
        self.slices: Mapping[str, slice] = MappingProxyType(slices)
        self.size = start

    def split(self, vector: ca.SX) -> dict[str, ca.SX]:
        """Symbolic blocks of ``vector`` by name."""
        return {name: vector[s] for name, s in self.slices.items()}

    def pack(self, blocks: Mapping[str, np.ndarray]) -> np.ndarray:
        """One flat vector from every named block (each must have its declared size)."""
        if set(blocks) != set(self.slices):
            raise ValueError(f"expected blocks {sorted(self.slices)}, got {sorted(blocks)}")
        out = np.empty(self.size)
        for name, s in self.slices.items():
            out[s] = np.asarray(blocks[name], dtype=float).ravel()
        return out


@dataclass(frozen=True)
class _Trajectory:
    """States (N+1 rows) and inputs (N rows) over the horizon starting at ``t_s``."""

    t_s: float
    states: np.ndarray
    inputs: np.ndarray


class KinematicNmpc:
    """Kinematic-bicycle NMPC path tracker with IPOPT (seed digest section 1).

    Args:
      config: the tracker configuration; ``config.model`` is the controller's belief
        about the car (only ``cog_front_m`` and ``cog_rear_m`` enter the kinematic model).

    The plan's node 0 is the state the optimisation started from: the estimate predicted
    over ``latency_s`` (and the estimate's age), i.e. the car at ``t_s + latency_s``; the
    plan's ``t_s`` and the command's ``t_s`` are the time of the step. The estimate's
    ``vx_mps`` stands for the model's speed (the CoG speed; ``vy`` is not read). A
    successful solve ends a fallback or a safe stop.
    """

    state_names: tuple[str, ...] = STATE_NAMES
    input_names: tuple[str, ...] = INPUT_NAMES

    def __init__(self, config: TrackerConfig) -> None:
        if config.name != "kinematic-nmpc":
            raise ConfigError(f"name = {config.name!r}: KinematicNmpc expects 'kinematic-nmpc'")
        self.config = config
        n = config.horizon
        self._n = n
        self._step_model = discrete_function(config.model, config.dt_s)
        self._predict_model = predict_function(config.model)
        self._params = _Layout(
            (
                ("state0", len(STATE_NAMES)),
                ("input_prev", len(INPUT_NAMES)),
                ("ref_x_m", n),
                ("ref_y_m", n),
                ("ref_yaw_rad", n),
                ("ref_speed_mps", n),
            )
        )
        self._constraints = _Layout(
            (
                ("initial_state", len(STATE_NAMES)),
                ("dynamics", len(STATE_NAMES) * n),
                ("steer_rate", n),
            )
        )
        self._n_state_vars = len(STATE_NAMES) * (n + 1)
        self._solver = self._build_solver()
        self._lbx, self._ubx = self._variable_bounds()
        self._lbg, self._ubg = self._constraint_bounds()
        self.reset()

    # ------------------------------------------------------------------ construction

    def _build_solver(self) -> ca.Function:
        """The multiple-shooting NLP, built once (section 1's cost and model)."""
        cfg = self.config
        w = cfg.weights
        n, dt = self._n, cfg.dt_s
        states = ca.SX.sym("states", len(STATE_NAMES), n + 1)
        inputs = ca.SX.sym("inputs", len(INPUT_NAMES), n)
        p = ca.SX.sym("p", self._params.size)
        par = self._params.split(p)

        cost = 0
        dynamics = []
        steer_rate = []
        previous = par["input_prev"]
        for k in range(n):
            u = inputs[:, k]
            dynamics.append(states[:, k + 1] - self._step_model(states[:, k], u))
            steer_rate.append(u[INPUT["steer_rad"]] - previous[INPUT["steer_rad"]])
            accel_rate = (u[INPUT["accel_mps2"]] - previous[INPUT["accel_mps2"]]) / dt
            steer_rate_radps = (u[INPUT["steer_rad"]] - previous[INPUT["steer_rad"]]) / dt
            cost += dt * (
                w.accel * u[INPUT["accel_mps2"]] ** 2
                + w.steer * u[INPUT["steer_rad"]] ** 2
                + w.accel_rate * accel_rate**2
                + w.steer_rate * steer_rate_radps**2
            )
            # Tracking terms at node k + 1 against reference point k (nodes 1..N).
            x = states[:, k + 1]
            ref_yaw = par["ref_yaw_rad"][k]
            dx = x[STATE["x_m"]] - par["ref_x_m"][k]
            dy = x[STATE["y_m"]] - par["ref_y_m"][k]
            cte = -ca.sin(ref_yaw) * dx + ca.cos(ref_yaw) * dy
            heading_error = x[STATE["yaw_rad"]] - ref_yaw
            speed_error = x[STATE["vx_mps"]] - par["ref_speed_mps"][k]
            cost += dt * (
                w.cte * cte**2 + w.heading * heading_error**2 + w.speed * speed_error**2
            )
            previous = u

        constraint_blocks = {
            "initial_state": states[:, 0] - par["state0"],
            "dynamics": ca.vertcat(*dynamics),
            "steer_rate": ca.vertcat(*steer_rate),
        }
        g = ca.vertcat(*(constraint_blocks[name] for name in self._constraints.slices))
        variables = ca.vertcat(ca.vec(states), ca.vec(inputs))
        options = {
            "print_time": False,
            "error_on_fail": False,
            "ipopt.print_level": 0,
            "ipopt.sb": "yes",
            "ipopt.max_iter": cfg.max_iterations,
            "ipopt.tol": cfg.tolerance,
        }
        return ca.nlpsol(
            "kinematic_nmpc", "ipopt", {"x": variables, "p": p, "f": cost, "g": g}, options
        )

    def _variable_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        cfg = self.config
        n_inputs = len(INPUT_NAMES) * self._n
        low_input = np.empty(len(INPUT_NAMES))
        high_input = np.empty(len(INPUT_NAMES))
        low_input[INPUT["accel_mps2"]] = cfg.accel_min_mps2
        high_input[INPUT["accel_mps2"]] = cfg.accel_max_mps2
        low_input[INPUT["steer_rad"]] = -cfg.max_steer_rad
        high_input[INPUT["steer_rad"]] = cfg.max_steer_rad
        lbx = np.concatenate([np.full(self._n_state_vars, -np.inf), np.tile(low_input, self._n)])
        ubx = np.concatenate([np.full(self._n_state_vars, np.inf), np.tile(high_input, self._n)])
        if lbx.size != self._n_state_vars + n_inputs:
            raise RuntimeError("kinematic NMPC: variable bounds do not match the NLP")
        return lbx, ubx

    def _constraint_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        rate_step = self.config.max_steer_rate_radps * self.config.dt_s
        sizes = {name: s.stop - s.start for name, s in self._constraints.slices.items()}
        low = {
            "initial_state": np.zeros(sizes["initial_state"]),
            "dynamics": np.zeros(sizes["dynamics"]),
            "steer_rate": np.full(sizes["steer_rate"], -rate_step),
        }
        high = dict(low, steer_rate=np.full(sizes["steer_rate"], rate_step))
        return self._constraints.pack(low), self._constraints.pack(high)

    # ------------------------------------------------------------------ public API

    def reset(self, previous_command: Command | None = None) -> None:
        """Forget every previous solution.

        ``previous_command`` is the actuation already applied to the car (default: zero
        acceleration and steering); the first step warm-starts from it held over the
        horizon and penalises its first input rate against it (seed section 1).
        """
        previous = np.zeros(len(INPUT_NAMES))
        if previous_command is not None:
            previous[INPUT["accel_mps2"]] = previous_command.accel_mps2
            previous[INPUT["steer_rad"]] = previous_command.steer_rad
        self._previous_input = previous
        self._previous_t_s: float | None = None
        self._warm: _Trajectory | None = None
        self._last_good: _Trajectory | None = None
        self._failing_since_t_s: float | None = None

    def step(
        self, t_s: float, estimate: Estimate, reference: ReferencePath
    ) -> tuple[Command, Plan]:
        """One control step: the command to apply at ``t_s`` and the plan behind it."""
        state0 = self._initial_state(t_s, estimate)
        if not np.all(np.isfinite(state0)):
            return self._fallback(t_s, state0, "non_finite_estimate", 0, 0.0)
        guess = self._initial_guess(t_s, state0)

        blocks = self._reference_blocks(reference, state0, guess.states)
        blocks["state0"] = state0
        blocks["input_prev"] = self._previous_input
        params = self._params.pack(blocks)
        w0 = np.concatenate([guess.states.ravel(), guess.inputs.ravel()])

        start = time.perf_counter()
        try:
            solution = self._solver(
                x0=w0, p=params, lbx=self._lbx, ubx=self._ubx, lbg=self._lbg, ubg=self._ubg
            )
            stats = self._solver.stats()
        except RuntimeError as error:  # CasADi evaluation errors: treat as a failed solve.
            solve_time_s = time.perf_counter() - start
            return self._fallback(t_s, state0, f"error: {error}", 0, solve_time_s)
        solve_time_s = time.perf_counter() - start

        status = str(stats.get("return_status", "unknown"))
        iterations = int(stats.get("iter_count", 0))
        w = np.asarray(solution["x"], dtype=float).ravel()
        cost = float(solution["f"])
        if not (stats.get("success", False) and np.all(np.isfinite(w)) and math.isfinite(cost)):
            return self._fallback(t_s, state0, status, iterations, solve_time_s)

        states = w[: self._n_state_vars].reshape(self._n + 1, len(STATE_NAMES))
        inputs = w[self._n_state_vars :].reshape(self._n, len(INPUT_NAMES))
        inputs = self._clip_inputs(inputs)
        trajectory = _Trajectory(t_s, states, inputs)
        self._last_good = trajectory
        self._failing_since_t_s = None
        plan = self._plan(trajectory, cost, solve_time_s, iterations, status, True, False)
        return self._commit(trajectory), plan

    # ------------------------------------------------------------------ helpers

    def _initial_state(self, t_s: float, estimate: Estimate) -> np.ndarray:
        """The estimate's state, predicted over its age and the latency (section 1)."""
        state = np.array([estimate[name] for name in _ESTIMATE_NAMES], dtype=float)
        duration_s = self.config.latency_s + max(0.0, t_s - estimate.t_s)
        if duration_s > 0.0 and np.all(np.isfinite(state)):
            state = np.asarray(
                self._predict_model(state, self._previous_input, duration_s), dtype=float
            ).ravel()
        return state

    def _rollout(self, state0: np.ndarray, inputs: np.ndarray) -> np.ndarray:
        states = np.empty((inputs.shape[0] + 1, len(STATE_NAMES)))
        states[0] = state0
        for k, u in enumerate(inputs):
            states[k + 1] = np.asarray(self._step_model(states[k], u), dtype=float).ravel()
        return states

    def _shifted_inputs(self, trajectory: _Trajectory, t_s: float) -> np.ndarray:
        """The inputs of ``trajectory`` from ``t_s`` on, the last one held past its end."""
        shift = max(0, int(round((t_s - trajectory.t_s) / self.config.dt_s)))
        index = np.minimum(np.arange(self._n) + shift, self._n - 1)
        return trajectory.inputs[index]

    def _initial_guess(self, t_s: float, state0: np.ndarray) -> _Trajectory:
        """Previous solution shifted by the elapsed time, else the last command held.

        ``state0`` must be finite.
        """
        if self._warm is None:
            inputs = np.tile(self._previous_input, (self._n, 1))
            return _Trajectory(t_s, self._rollout(state0, inputs), inputs)
        warm = self._warm
        shift = max(0, int(round((t_s - warm.t_s) / self.config.dt_s)))
        inputs = self._shifted_inputs(warm, t_s)
        states = np.empty((self._n + 1, len(STATE_NAMES)))
        keep = max(0, self._n + 1 - shift)
        states[:keep] = warm.states[shift : shift + keep]
        for k in range(keep, self._n + 1):
            source = states[k - 1] if k > 0 else warm.states[-1]
            states[k] = np.asarray(self._step_model(source, inputs[k - 1]), dtype=float).ravel()
        # Rebase the yaw by whole turns onto the current yaw, then pin node 0.
        yaw = STATE["yaw_rad"]
        turns = np.round((state0[yaw] - states[0, yaw]) / (2.0 * np.pi))
        states[:, yaw] += 2.0 * np.pi * turns
        states[0] = state0
        return _Trajectory(t_s, states, inputs)

    def _reference_blocks(
        self, reference: ReferencePath, state0: np.ndarray, guess_states: np.ndarray
    ) -> dict[str, np.ndarray]:
        """Reference points at the arc lengths the warm start expects to cover."""
        dt = self.config.dt_s
        projection = reference.project(state0[STATE["x_m"]], state0[STATE["y_m"]])
        speed = np.maximum(guess_states[:, STATE["vx_mps"]], 0.0)
        s = projection.s_m + np.cumsum(0.5 * (speed[:-1] + speed[1:]) * dt)
        samples = reference.sample(s)
        yaw = np.unwrap(np.concatenate(([projection.path_yaw_rad], samples["yaw_rad"])))
        turns = np.round((state0[STATE["yaw_rad"]] - yaw[0]) / (2.0 * np.pi))
        yaw = yaw[1:] + 2.0 * np.pi * turns
        return {
            "ref_x_m": samples["x_m"],
            "ref_y_m": samples["y_m"],
            "ref_yaw_rad": yaw,
            "ref_speed_mps": np.full(self._n, reference.speed_mps),
        }

    def _clip_inputs(self, inputs: np.ndarray) -> np.ndarray:
        """IPOPT may end a hair outside a bound; the command never does."""
        low = self._lbx[self._n_state_vars :].reshape(self._n, len(INPUT_NAMES))
        high = self._ubx[self._n_state_vars :].reshape(self._n, len(INPUT_NAMES))
        return np.clip(inputs, low, high)

    def _commit(self, trajectory: _Trajectory) -> Command:
        """Apply the trajectory's first input: remember it and keep the rest as warm start."""
        first = trajectory.inputs[0]
        self._previous_input = first.copy()
        self._previous_t_s = trajectory.t_s
        self._warm = trajectory
        return Command(
            t_s=trajectory.t_s,
            accel_mps2=float(first[INPUT["accel_mps2"]]),
            steer_rad=float(first[INPUT["steer_rad"]]),
        )

    def _fallback(
        self, t_s: float, state0: np.ndarray, status: str, iterations: int, solve_time_s: float
    ) -> tuple[Command, Plan]:
        """Replay the last good plan shifted; after ``fallback_time_s``, a safe stop."""
        if self._failing_since_t_s is None:
            self._failing_since_t_s = t_s
        failing_for_s = t_s - self._failing_since_t_s
        if failing_for_s > self.config.fallback_time_s + _TIME_EPS_S:
            inputs = self._safe_stop_inputs(t_s, state0)
            status = f"safe_stop ({status})"
        elif self._last_good is not None:
            inputs = self._shifted_inputs(self._last_good, t_s)
            status = f"fallback ({status})"
        else:
            inputs = np.tile(self._previous_input, (self._n, 1))
            status = f"fallback ({status})"
        inputs = self._clip_inputs(inputs)
        if np.all(np.isfinite(state0)):
            states = self._rollout(state0, inputs)
        else:
            states = np.full((self._n + 1, len(STATE_NAMES)), np.nan)
        trajectory = _Trajectory(t_s, states, inputs)
        plan = self._plan(trajectory, math.nan, solve_time_s, iterations, status, False, True)
        command = self._commit(trajectory)
        if not np.all(np.isfinite(states)):
            self._warm = None  # never warm-start from a non-finite guess
        return command, plan

    def _safe_stop_inputs(self, t_s: float, state0: np.ndarray) -> np.ndarray:
        """Steering to zero at the rate limit, then held; braking until standstill."""
        cfg = self.config
        first_period_s = cfg.dt_s if self._previous_t_s is None else t_s - self._previous_t_s
        steer_step = cfg.max_steer_rate_radps * np.concatenate(
            ([max(first_period_s, 0.0)], np.full(self._n - 1, cfg.dt_s))
        )
        steer0 = self._previous_input[INPUT["steer_rad"]]
        steer = np.sign(steer0) * np.maximum(abs(steer0) - np.cumsum(steer_step), 0.0)
        speed = state0[STATE["vx_mps"]] if np.isfinite(state0[STATE["vx_mps"]]) else 0.0
        inputs = np.zeros((self._n, len(INPUT_NAMES)))
        inputs[:, INPUT["steer_rad"]] = steer
        for k in range(self._n):
            # Brake no further than to standstill within the stage.
            accel = max(cfg.safe_stop_accel_mps2, -max(speed, 0.0) / cfg.dt_s)
            inputs[k, INPUT["accel_mps2"]] = accel
            speed += accel * cfg.dt_s
        return inputs

    def _plan(
        self,
        trajectory: _Trajectory,
        cost: float,
        solve_time_s: float,
        iterations: int,
        status: str,
        success: bool,
        fallback: bool,
    ) -> Plan:
        return Plan(
            t_s=trajectory.t_s,
            dt_s=self.config.dt_s,
            state_names=STATE_NAMES,
            states=trajectory.states.copy(),
            input_names=INPUT_NAMES,
            inputs=trajectory.inputs.copy(),
            cost=cost,
            solve_time_s=solve_time_s,
            iterations=iterations,
            status=status,
            success=success,
            fallback=fallback,
        )
