"""The NLP machinery every nonlinear MPC path tracker shares (seed digest section 1).

At every control step solve, by multiple shooting with IPOPT,
``min_{x,u} sum_k c_k(x_k, u_k)  s.t.  x_{k+1} = F(x_k, u_k), x_0 = estimated state``,
apply the first input and keep the rest as the next warm start. A tracker is an
:class:`NmpcModel` (the model ``F`` and how its state is formed from an estimate) plus a
:class:`tracker.config.TrackerConfig`; :class:`Nmpc` does the rest:

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
* Latency (section 1, item (a)): the initial state is predicted forward over
  ``latency_s`` plus the actuator lag the model leaves out (``unmodelled_lag_s``) plus the
  age of the estimate, with the previous command, before the optimisation starts.
* Warm start: the previous solution shifted by the time elapsed; on the first step the
  last applied actuation held over the horizon and rolled out through the model (section
  1, "warm start").
* Failures: the solver status is checked every step. On failure, or on a non-finite
  result, the last good plan is replayed, shifted by the elapsed time (``fallback=True``);
  once failures have lasted longer than ``fallback_time_s`` the tracker commands a safe
  stop: steering back to zero at the steering-rate limit, then held, and a constant
  deceleration to standstill. :meth:`Nmpc.step` never raises for a solver failure.

The NLP is built once in the constructor; a step only sets parameters and solves. Nothing
depends on wall-clock time except the reported ``solve_time_s``, so equal inputs give
equal outputs.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import casadi as ca
import numpy as np

from cosim.exceptions import ConfigError
from cosim.records import Command, Estimate, Plan
from tracker.config import TrackerConfig
from tracker.reference_path import ReferencePath

INPUT_NAMES: tuple[str, ...] = ("accel_mps2", "steer_rad")
"""Inputs of every NMPC model: the :class:`cosim.records.Command` fields, in vector order."""

INPUT = MappingProxyType({name: i for i, name in enumerate(INPUT_NAMES)})
"""Read-only map from input name to its index in the input vector."""

REQUIRED_STATE_NAMES: tuple[str, ...] = ("x_m", "y_m", "yaw_rad", "vx_mps")
"""States the cost and the safe stop read: CoG position (world frame), yaw, forward speed."""

_TIME_EPS_S = 1e-9
"""Slack when comparing simulated times, against float round-off of sums of periods."""


@dataclass(frozen=True)
class NmpcModel:
    """A vehicle model as the shared NMPC needs it.

    ``step`` is ``F(state, inputs) -> next_state`` over one stage of ``dt_s``; ``predict``
    is ``P(state, inputs, duration_s) -> state`` for a variable duration (latency, elapsed
    time); both hold the inputs over the interval. ``estimated_state_names`` are read from
    the :class:`~cosim.records.Estimate` by name; every other state is internal and
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
    internal_rest_inputs: Mapping[str, str] = field(default_factory=dict)
    input_names: tuple[str, ...] = INPUT_NAMES
    limits: ca.Function | None = None
    """``h(state) -> limited quantities`` (e.g. tyre slip angles), or None."""
    limit_names: tuple[str, ...] = ()
    """Names of ``h``'s outputs, in order (units in the names)."""
    limit_bounds: tuple[float, ...] = ()
    """``h_max`` for each of ``h``'s outputs: the soft bound ``|h| <= h_max``."""

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
        n_x, n_u = len(self.state_names), len(self.input_names)
        for function, n_in in ((self.step, 2), (self.predict, 3)):
            if (function.n_in() != n_in or function.size1_in(0) != n_x
                    or function.size1_in(1) != n_u or function.size1_out(0) != n_x):
                raise ConfigError(f"model {self.name}: {function.name()} does not match "
                                  f"{n_x} states and {n_u} inputs")


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


class Nmpc:
    """Nonlinear MPC path tracker with IPOPT on any :class:`NmpcModel` (seed section 1).

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
        self._variables = _Layout(
            (
                ("states", self._n_x * (n + 1)),
                ("inputs", len(INPUT_NAMES) * n),
            )
        )
        self._params = _Layout(
            (
                ("state0", self._n_x),
                ("input_prev", len(INPUT_NAMES)),
                ("ref_x_m", n),
                ("ref_y_m", n),
                ("ref_yaw_rad", n),
                ("ref_speed_mps", n),
            )
        )
        self._constraints = _Layout(
            (
                ("initial_state", self._n_x),
                ("dynamics", self._n_x * n),
                ("steer_rate", n),
            )
        )
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
        index = self._state
        states = ca.SX.sym("states", self._n_x, n + 1)
        inputs = ca.SX.sym("inputs", len(INPUT_NAMES), n)
        p = ca.SX.sym("p", self._params.size)
        par = self._params.split(p)
        limit_bounds = ca.DM(list(self.model.limit_bounds))

        cost = 0
        dynamics = []
        steer_rate = []
        previous = par["input_prev"]
        for k in range(n):
            u = inputs[:, k]
            dynamics.append(states[:, k + 1] - self.model.step(states[:, k], u))
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
            dx = x[index["x_m"]] - par["ref_x_m"][k]
            dy = x[index["y_m"]] - par["ref_y_m"][k]
            cte = -ca.sin(ref_yaw) * dx + ca.cos(ref_yaw) * dy
            heading_error = x[index["yaw_rad"]] - ref_yaw
            speed_error = x[index["vx_mps"]] - par["ref_speed_mps"][k]
            cost += dt * (
                w.cte * cte**2 + w.heading * heading_error**2 + w.speed * speed_error**2
            )
            if self.model.limits is not None:
                h = self.model.limits(x)
                excess = ca.fmax(ca.fabs(h) - limit_bounds, 0.0)
                cost += dt * w.limit_excess * ca.sumsqr(excess)
            previous = u

        constraint_blocks = {
            "initial_state": states[:, 0] - par["state0"],
            "dynamics": ca.vertcat(*dynamics),
            "steer_rate": ca.vertcat(*steer_rate),
        }
        g = ca.vertcat(*(constraint_blocks[name] for name in self._constraints.slices))
        variable_blocks = {"states": ca.vec(states), "inputs": ca.vec(inputs)}
        variables = ca.vertcat(*(variable_blocks[name] for name in self._variables.slices))
        options = {
            "print_time": False,
            "error_on_fail": False,
            "ipopt.print_level": 0,
            "ipopt.sb": "yes",
            "ipopt.max_iter": cfg.max_iterations,
            "ipopt.tol": cfg.tolerance,
        }
        return ca.nlpsol(
            self.model.name.replace("-", "_"), "ipopt",
            {"x": variables, "p": p, "f": cost, "g": g}, options,
        )

    def _variable_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        cfg = self.config
        n_states = self._n_x * (self._n + 1)
        low_input = np.empty(len(INPUT_NAMES))
        high_input = np.empty(len(INPUT_NAMES))
        low_input[INPUT["accel_mps2"]] = cfg.accel_min_mps2
        high_input[INPUT["accel_mps2"]] = cfg.accel_max_mps2
        low_input[INPUT["steer_rad"]] = -cfg.max_steer_rad
        high_input[INPUT["steer_rad"]] = cfg.max_steer_rad
        low = {"states": np.full(n_states, -np.inf), "inputs": np.tile(low_input, self._n)}
        high = {"states": np.full(n_states, np.inf), "inputs": np.tile(high_input, self._n)}
        return self._variables.pack(low), self._variables.pack(high)

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
        horizon, penalises its first input rate against it (seed section 1) and starts
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
        self._failing_since_t_s: float | None = None
        self._last_state: tuple[float, np.ndarray] | None = None

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
        w0 = self._variables.pack({"states": guess.states.ravel(),
                                   "inputs": guess.inputs.ravel()})

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

        blocks_out = {name: w[s] for name, s in self._variables.slices.items()}
        states = blocks_out["states"].reshape(self._n + 1, self._n_x)
        inputs = self._clip_inputs(blocks_out["inputs"].reshape(self._n, len(INPUT_NAMES)))
        trajectory = _Trajectory(t_s, states, inputs)
        self._last_good = trajectory
        self._failing_since_t_s = None
        plan = self._plan(trajectory, cost, solve_time_s, iterations, status, True, False)
        return self._commit(trajectory), plan

    # ------------------------------------------------------------------ helpers

    def _predict(self, state: np.ndarray, inputs: np.ndarray, duration_s: float) -> np.ndarray:
        return np.asarray(self.model.predict(state, inputs, duration_s), dtype=float).ravel()

    def _internal_states(self, t_s: float) -> dict[str, float]:
        """The internal states at ``t_s``: last step's state propagated with the command
        applied since (exact for an actuator it drives), else at rest at that command."""
        rest = {name: float(self._previous_input[INPUT[input_name]])
                for name, input_name in self.model.internal_rest_inputs.items()}
        if not rest or self._last_state is None:
            return rest
        last_t_s, last_state = self._last_state
        elapsed_s = t_s - last_t_s
        state = last_state
        if elapsed_s > 0.0:
            filled = np.where(np.isfinite(last_state), last_state, 0.0)
            state = self._predict(filled, self._previous_input, elapsed_s)
        values = {name: float(state[self._state[name]]) for name in rest}
        return values if all(math.isfinite(v) for v in values.values()) else rest

    def _initial_state(self, t_s: float, estimate: Estimate) -> np.ndarray:
        """The estimate's states and the internal ones, predicted over the estimate's age,
        the latency and the model's unmodelled lag (section 1, item (a))."""
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
        duration_s = (self.config.latency_s + self.model.unmodelled_lag_s
                      + max(0.0, t_s - estimate.t_s))
        if duration_s > 0.0 and np.all(np.isfinite(state)):
            state = self._predict(state, self._previous_input, duration_s)
        return state

    def _rollout(self, state0: np.ndarray, inputs: np.ndarray) -> np.ndarray:
        states = np.empty((inputs.shape[0] + 1, self._n_x))
        states[0] = state0
        for k, u in enumerate(inputs):
            states[k + 1] = np.asarray(self.model.step(states[k], u), dtype=float).ravel()
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
        states = np.empty((self._n + 1, self._n_x))
        keep = max(0, self._n + 1 - shift)
        states[:keep] = warm.states[shift : shift + keep]
        for k in range(keep, self._n + 1):
            source = states[k - 1] if k > 0 else warm.states[-1]
            states[k] = np.asarray(self.model.step(source, inputs[k - 1]), dtype=float).ravel()
        # Rebase the yaw by whole turns onto the current yaw, then pin node 0.
        yaw = self._state["yaw_rad"]
        turns = np.round((state0[yaw] - states[0, yaw]) / (2.0 * np.pi))
        states[:, yaw] += 2.0 * np.pi * turns
        states[0] = state0
        return _Trajectory(t_s, states, inputs)

    def _reference_blocks(
        self, reference: ReferencePath, state0: np.ndarray, guess_states: np.ndarray
    ) -> dict[str, np.ndarray]:
        """Reference points at the arc lengths the warm start expects to cover."""
        dt = self.config.dt_s
        index = self._state
        projection = reference.project(state0[index["x_m"]], state0[index["y_m"]])
        speed = np.maximum(guess_states[:, index["vx_mps"]], 0.0)
        s = projection.s_m + np.cumsum(0.5 * (speed[:-1] + speed[1:]) * dt)
        samples = reference.sample(s)
        yaw = np.unwrap(np.concatenate(([projection.path_yaw_rad], samples["yaw_rad"])))
        turns = np.round((state0[index["yaw_rad"]] - yaw[0]) / (2.0 * np.pi))
        yaw = yaw[1:] + 2.0 * np.pi * turns
        return {
            "ref_x_m": samples["x_m"],
            "ref_y_m": samples["y_m"],
            "ref_yaw_rad": yaw,
            "ref_speed_mps": np.full(self._n, reference.speed_mps),
        }

    def _clip_inputs(self, inputs: np.ndarray) -> np.ndarray:
        """IPOPT may end a hair outside a bound; the command never does."""
        s = self._variables.slices["inputs"]
        low = self._lbx[s].reshape(self._n, len(INPUT_NAMES))
        high = self._ubx[s].reshape(self._n, len(INPUT_NAMES))
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
            states = np.full((self._n + 1, self._n_x), np.nan)
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
        speed = state0[self._state["vx_mps"]]
        speed = speed if np.isfinite(speed) else 0.0
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
        )
