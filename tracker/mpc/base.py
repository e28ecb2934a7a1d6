"""The skeleton every MPC path tracker shares: one control step, its fallback, its plan.

A step (:meth:`MpcTracker.step`) is the same for the nonlinear MPC (:mod:`tracker.mpc.nmpc`),
the linear time-varying one (:mod:`tracker.mpc.ltv_mpc`) and the delta-u one
(:mod:`tracker.mpc.dynamic_mpc`); each specialises only the formulation (as do-mpc's
``controller/`` shares one optimizer base and acados separates the problem from the solver):

1. **Start** (:meth:`MpcTracker._start`, the tracker's): the state the optimisation starts
   from, the estimate predicted over its age and the believed latency (an estimate that
   lacks a state the model needs is a configuration error, raised).
2. **Solve** (:meth:`MpcTracker._solve`, the tracker's): warm start, reference, the solver
   call; a :class:`Solved` with the planned states and inputs, the cost and the solver's
   own verdict.
3. **Accept or fall back** (here). A solve counts when the solver says it succeeded and
   the states, inputs and cost are finite; the inputs are then clipped onto the bounds (a
   solver ends a hair outside them) and the plan is kept as the last good one. Otherwise
   :meth:`MpcTracker._fallback`: the last good plan replayed, shifted by the time elapsed;
   once failures have lasted longer than ``tracker.fallback_time_s`` a safe stop
   (:mod:`tracker.mpc.fallback`). A non-finite start falls back before any solve.
4. **Commit** (here): the first input is the command; it is recorded in the delay line the
   tracker believes in (:class:`tracker.mpc.delay_line.IssuedInputs`) and the trajectory is
   the next warm start.

What a failed solve may raise is caught, and nothing else: :data:`SOLVER_ERRORS`. A
numerical failure inside a step (CasADi's evaluation errors, a singular matrix, an
overflow) becomes a fallback with status ``error: <type>: <message>``; a programming error
(``TypeError``, ``KeyError`` ...) still ends the run, where it can be seen.

The speed a safe stop brakes from is the start's; without a finite start, the last good
plan's speed at the step's time; without either, the reference's top speed, so that the
stop brakes over the whole horizon rather than coasting (:meth:`MpcTracker._stop_speed_mps`).

Wall time is measured around the whole step (:attr:`MpcTracker.timing`) beside the
solver's own ``solve_time_s``; nothing else depends on the clock, so equal inputs give
equal outputs.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

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
    shifted_plan,
    stages_elapsed,
)
from tracker.paths.reference_path import ReferencePath

SOLVER_ERRORS: tuple[type[Exception], ...] = (RuntimeError, ArithmeticError, ValueError)
"""What a failed solve raises and a step turns into a fallback: CasADi's evaluation and
plug-in errors (``RuntimeError``), overflows and divisions by zero (``ArithmeticError``),
non-finite or singular arrays (``ValueError``, numpy's ``LinAlgError`` included)."""


def _error_status(error: Exception) -> str:
    """The plan's status for a step that raised one of :data:`SOLVER_ERRORS`."""
    return f"error: {type(error).__name__}: {error}"


@dataclass(frozen=True)
class Start:
    """The state the optimisation starts from, at ``t_s`` (the step's time plus the
    latency), in the tracker's model coordinates."""

    t_s: float
    state: np.ndarray
    caution: float = 1.0
    """The factor on the steering-rate weight from the estimate's uncertainty across the car
    (:mod:`tracker.mpc.caution`); 1 where the tracker takes none."""

    @property
    def finite(self) -> bool:
        return bool(np.isfinite(self.state).all())


@dataclass(frozen=True)
class Trajectory:
    """States (N+1 rows) and inputs (N rows) of a plan made at ``t_s``, node 0 at
    ``start_t_s``."""

    t_s: float
    start_t_s: float
    states: np.ndarray
    inputs: np.ndarray


@dataclass(frozen=True)
class Solved:
    """What one solve produced, before the skeleton accepts it."""

    states: np.ndarray
    inputs: np.ndarray
    cost: float
    status: str
    """The solver's own status (``Solve_Succeeded``, ``MAX_ITER`` ...)."""
    iterations: int
    success: bool
    """The solver's own verdict."""
    solve_time_s: float
    """Wall time of the solver call (the plan's ``solve_time_s``)."""
    setup_s: float = 0.0
    """Wall time of what the step computes for the solver beforehand (the LTV-MPC's
    linearisation); 0 where the solver call does it all."""
    speed_reduced: bool = False
    """The plan slowed below the reference speed for grip (:mod:`tracker.mpc.grip_speed`)."""


@dataclass(frozen=True)
class StepTiming:
    """Wall times of the last :meth:`MpcTracker.step` [s]."""

    setup_s: float
    """What the step computes for the solver before calling it (:attr:`Solved.setup_s`)."""
    solve_s: float
    """The solver call (the plan's ``solve_time_s``)."""
    step_s: float
    """The whole step, from the estimate to the command."""


class MpcTracker:
    """The shared control step of the MPC trackers (module docstring).

    A tracker calls ``super().__init__`` with its stage length and horizon (the plan's
    ``dt_s`` and node count), its input bounds, the index of ``vx_mps`` in its state vector
    and the delay it believes in, then ``self.reset()``; it implements :meth:`_start`,
    :meth:`_solve` and :meth:`_rollout`, and may override :meth:`_clip_solution`,
    :meth:`_plan_states`, :meth:`_accept_previous` and :meth:`_forget`.
    """

    state_names: tuple[str, ...]
    input_names: tuple[str, ...] = INPUT_NAMES

    def __init__(self, config: TrackerConfig, stage_dt_s: float, horizon: int,
                 input_low: np.ndarray, input_high: np.ndarray, speed_index: int,
                 delay_s: float) -> None:
        self.config = config
        self._stage_dt_s = stage_dt_s
        self._n = horizon
        self._input_low, self._input_high = input_low, input_high
        self._speed_index = speed_index
        self._issued = IssuedInputs(delay_s, np.zeros(len(INPUT_NAMES)))
        self._failures = FailureClock(config.fallback_time_s)
        self.timing = StepTiming(math.nan, math.nan, math.nan)

    # ------------------------------------------------------------------ public API

    def reset(self, previous_command: Command | None = None) -> None:
        """Forget every previous step.

        ``previous_command`` is the actuation already applied to the car (default: zero
        acceleration and steering); the first step takes its first input rate against it,
        warm-starts from it held over the horizon and starts the tracker's own actuator
        states at rest at it.
        """
        previous = np.zeros(len(INPUT_NAMES))
        if previous_command is not None:
            previous[INPUT["accel_mps2"]] = previous_command.accel_mps2
            previous[INPUT["steer_rad"]] = previous_command.steer_rad
        self._previous_input = self._accept_previous(previous)
        self._previous_t_s: float | None = None
        self._issued.reset(self._previous_input)
        self._failures.reset()
        self._warm: Trajectory | None = None
        self._last_good: Trajectory | None = None
        self._path: ReferencePath | None = None
        self._forget()

    def step(
        self, t_s: float, estimate: Estimate, reference: ReferencePath
    ) -> tuple[Command, Plan]:
        """One control step: the command to apply at ``t_s`` and the plan behind it."""
        began = time.perf_counter()
        self._path = reference
        try:
            start = self._start(t_s, estimate, reference)
        except SOLVER_ERRORS as error:
            unknown = Start(t_s, np.full(len(self.state_names), np.nan))
            return self._fallback(t_s, unknown, _error_status(error), 0, 0.0, began)
        if not start.finite:
            return self._fallback(t_s, start, "non_finite_estimate", 0, 0.0, began)
        solve_began = time.perf_counter()
        try:
            solved = self._solve(t_s, start, reference)
        except SOLVER_ERRORS as error:
            return self._fallback(t_s, start, _error_status(error), 0,
                                  time.perf_counter() - solve_began, began)
        if not (solved.success and math.isfinite(solved.cost)
                and np.isfinite(solved.states).all() and np.isfinite(solved.inputs).all()):
            return self._fallback(t_s, start, solved.status, solved.iterations,
                                  solved.solve_time_s, began, solved.setup_s)
        trajectory = Trajectory(t_s, start.t_s, solved.states,
                                self._clip_solution(solved.inputs))
        self._last_good = trajectory
        self._failures.reset()
        plan = self._plan(trajectory, start, solved.cost, solved.solve_time_s,
                          solved.iterations, solved.status, True, False, solved.speed_reduced)
        command = self._commit(trajectory)
        self.timing = StepTiming(solved.setup_s, solved.solve_time_s,
                                 time.perf_counter() - began)
        return command, plan

    # ------------------------------------------------------------------ the tracker's part

    def _start(self, t_s: float, estimate: Estimate, reference: ReferencePath) -> Start:
        """The state the optimisation starts from (module docstring, item 1)."""
        raise NotImplementedError

    def _solve(self, t_s: float, start: Start, reference: ReferencePath) -> Solved:
        """Warm start, reference and one solve from the finite ``start`` (item 2)."""
        raise NotImplementedError

    def _rollout(self, start: Start, inputs: np.ndarray) -> np.ndarray:
        """The tracker's model driven by ``inputs`` from the finite ``start``: N+1 rows."""
        raise NotImplementedError

    def _clip_solution(self, inputs: np.ndarray) -> np.ndarray:
        """A solution's inputs exactly within the bounds (a solver meets them only to its
        tolerance)."""
        return np.clip(inputs, self._input_low, self._input_high)

    def _plan_states(self, trajectory: Trajectory,
                     start: Start) -> tuple[tuple[str, ...], np.ndarray]:
        """The plan's state names and states (the model's, by default)."""
        return self.state_names, trajectory.states.copy()

    def _accept_previous(self, previous: np.ndarray) -> np.ndarray:
        """The previously applied input as the tracker takes it (as it is, by default)."""
        return previous

    def _forget(self) -> None:
        """Forget the tracker's own memory (called by :meth:`reset`)."""

    # ------------------------------------------------------------------ shared machinery

    def _warm_start(self, t_s: float, state0: np.ndarray, step: object,
                    yaw_index: int) -> Trajectory:
        """The previous plan shifted by the elapsed time (its tail rolled out with the
        model's one-stage ``step``, node 0 pinned to ``state0``), else the last applied
        input held over the horizon and rolled out."""
        if self._warm is None:
            inputs = np.tile(self._previous_input, (self._n, 1))
            return Trajectory(t_s, t_s, self._rollout(Start(t_s, state0), inputs), inputs)
        warm, dt_s = self._warm, self._stage_dt_s
        states, inputs = shifted_plan(warm.states, warm.inputs, warm.t_s, t_s, dt_s,
                                      step, state0, yaw_index)  # type: ignore[arg-type]
        return Trajectory(t_s, t_s, states, inputs)

    def _first_period_s(self, t_s: float) -> float:
        """Time since the last command; on the first step the shorter of the control
        period and a stage."""
        if self._previous_t_s is None:
            return min(self.config.dt_s, self._stage_dt_s)
        return max(t_s - self._previous_t_s, 0.0)

    def _stop_speed_mps(self, t_s: float, start: Start) -> float:
        """The speed a safe stop brakes from (module docstring)."""
        speed = float(start.state[self._speed_index])
        if math.isfinite(speed):
            return speed
        last = self._last_good
        if last is not None:
            node = min(stages_elapsed(last.t_s, t_s, self._stage_dt_s), self._n)
            speed = float(last.states[node, self._speed_index])
            if math.isfinite(speed):
                return speed
        return self._path.speed_mps if self._path is not None else 0.0

    def _fallback(self, t_s: float, start: Start, status: str, iterations: int,
                  solve_time_s: float, began: float, setup_s: float = 0.0
                  ) -> tuple[Command, Plan]:
        """Replay the last good plan shifted; after ``fallback_time_s``, a safe stop."""
        cfg = self.config
        if self._failures.fail(t_s):
            inputs = safe_stop_inputs(
                self._n, self._stage_dt_s, self._first_period_s(t_s),
                steer_rad=float(self._previous_input[INPUT["steer_rad"]]),
                speed_mps=self._stop_speed_mps(t_s, start),
                max_steer_rate_radps=cfg.max_steer_rate_radps,
                accel_mps2=cfg.safe_stop_accel_mps2,
            )
            status = f"safe_stop ({status})"
        elif self._last_good is not None:
            inputs = shifted_inputs(self._last_good.inputs, self._last_good.t_s, t_s,
                                    self._stage_dt_s)
            status = f"fallback ({status})"
        else:
            inputs = np.tile(self._previous_input, (self._n, 1))
            status = f"fallback ({status})"
        inputs = np.clip(inputs, self._input_low, self._input_high)
        if start.finite:
            states = self._rollout(start, inputs)
        else:
            states = np.full((self._n + 1, len(self.state_names)), np.nan)
        trajectory = Trajectory(t_s, start.t_s, states, inputs)
        plan = self._plan(trajectory, start, math.nan, solve_time_s, iterations, status,
                          False, True)
        command = self._commit(trajectory)
        if not np.all(np.isfinite(states)):
            self._warm = None  # never warm-start from a non-finite guess
        self.timing = StepTiming(setup_s, solve_time_s, time.perf_counter() - began)
        return command, plan

    def _commit(self, trajectory: Trajectory) -> Command:
        """Apply the trajectory's first input: remember it, record it in the delay line and
        keep the trajectory as the next warm start."""
        first = trajectory.inputs[0]
        self._previous_input = first.copy()
        self._previous_t_s = trajectory.t_s
        self._issued.record(trajectory.t_s, first)
        self._warm = trajectory
        return first_command(trajectory.t_s, trajectory.inputs)

    def _plan(self, trajectory: Trajectory, start: Start, cost: float, solve_time_s: float,
              iterations: int, status: str, success: bool, fallback: bool,
              speed_reduced: bool = False) -> Plan:
        state_names, states = self._plan_states(trajectory, start)
        return Plan(
            t_s=trajectory.t_s,
            dt_s=self._stage_dt_s,
            state_names=state_names,
            states=states,
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
