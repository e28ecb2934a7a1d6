"""What every MPC tracker does when its solver fails, and how it reuses its last plan.

A failed or non-finite solve never stops a run. The tracker replays its last good plan,
shifted by the time elapsed since it was made (:func:`shifted_inputs`); once failures have
lasted longer than ``tracker.fallback_time_s`` (:class:`FailureClock`) it commands a safe
stop (:func:`safe_stop_inputs`): the steering back to zero at the steering-rate limit, then
held, and a constant deceleration to standstill. Every such step counts in the run's
``solver_failures`` (the plan's ``fallback`` flag) and logs its status.

Inputs are ``(N, 2)`` arrays with columns :data:`INPUT_NAMES`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from types import MappingProxyType

import numpy as np

from cosim.core.records import Command

INPUT_NAMES: tuple[str, ...] = ("accel_mps2", "steer_rad")
"""Inputs of every MPC tracker: the :class:`cosim.core.records.Command` fields, in vector order."""

INPUT = MappingProxyType({name: i for i, name in enumerate(INPUT_NAMES)})
"""Read-only map from input name to its column in an input array."""

_TIME_EPS_S = 1e-9


class FailureClock:
    """How long the solver has been failing, and whether a safe stop is due.

    Args:
      fallback_time_s: how long to replay the last plan before the safe stop.
    """

    def __init__(self, fallback_time_s: float) -> None:
        self.fallback_time_s = fallback_time_s
        self._failing_since_t_s: float | None = None

    def reset(self) -> None:
        """The solver is not failing (after a success, or at the start of a run)."""
        self._failing_since_t_s = None

    def fail(self, t_s: float) -> bool:
        """Record a failure at ``t_s``; True when failures have lasted past the limit."""
        if self._failing_since_t_s is None:
            self._failing_since_t_s = t_s
        return t_s - self._failing_since_t_s > self.fallback_time_s + _TIME_EPS_S


def shifted_inputs(inputs: np.ndarray, plan_t_s: float, t_s: float, dt_s: float) -> np.ndarray:
    """The rows of a plan made at ``plan_t_s`` from ``t_s`` on, the last row held past its
    end; the same number of rows as ``inputs``."""
    n = inputs.shape[0]
    shift = stages_elapsed(plan_t_s, t_s, dt_s)
    return inputs[np.minimum(np.arange(n) + shift, n - 1)].copy()


def stages_elapsed(plan_t_s: float, t_s: float, dt_s: float) -> int:
    """Whole stages of ``dt_s`` from a plan made at ``plan_t_s`` to ``t_s`` (none before it)."""
    return max(0, int(round((t_s - plan_t_s) / dt_s)))


def safe_stop_inputs(
    n: int,
    dt_s: float,
    first_period_s: float,
    steer_rad: float,
    speed_mps: float,
    max_steer_rate_radps: float,
    accel_mps2: float,
) -> np.ndarray:
    """``n`` stages of a safe stop from the applied ``steer_rad`` at ``speed_mps``.

    The steering returns to zero at ``max_steer_rate_radps`` (the first stage lasting
    ``first_period_s``, the time since the previous command), then stays there; the
    deceleration ``accel_mps2`` (negative) is cut in the stage that reaches standstill, so
    the car never reverses.
    """
    steer_step = max_steer_rate_radps * np.concatenate(
        ([max(first_period_s, 0.0)], np.full(n - 1, dt_s))
    )
    steer = np.sign(steer_rad) * np.maximum(abs(steer_rad) - np.cumsum(steer_step), 0.0)
    speed = speed_mps if np.isfinite(speed_mps) else 0.0
    inputs = np.zeros((n, len(INPUT_NAMES)))
    inputs[:, INPUT["steer_rad"]] = steer
    for k in range(n):
        accel = max(accel_mps2, -max(speed, 0.0) / dt_s)
        inputs[k, INPUT["accel_mps2"]] = accel
        speed += accel * dt_s
    return inputs


def shifted_plan(
    states: np.ndarray,
    inputs: np.ndarray,
    plan_t_s: float,
    t_s: float,
    dt_s: float,
    step: Callable[[np.ndarray, np.ndarray], np.ndarray],
    state0: np.ndarray,
    yaw_index: int,
) -> tuple[np.ndarray, np.ndarray]:
    """The states and inputs of a plan made at ``plan_t_s``, from ``t_s`` on (the warm
    start): the inputs of :func:`shifted_inputs`, and the states shifted alike.

    Nodes past the plan's end are rolled out with ``step`` (one stage of the model) and the
    held inputs; the yaw is moved by whole turns onto ``state0``'s and node 0 pinned to
    ``state0``, the state the new plan starts from.
    """
    n = inputs.shape[0]
    shift = stages_elapsed(plan_t_s, t_s, dt_s)
    held = shifted_inputs(inputs, plan_t_s, t_s, dt_s)
    out = np.empty_like(states)
    keep = max(0, n + 1 - shift)
    out[:keep] = states[shift:shift + keep]
    for k in range(keep, n + 1):
        source = out[k - 1] if k > 0 else states[-1]
        out[k] = np.asarray(step(source, held[k - 1]), dtype=float).ravel()
    turns = (float(state0[yaw_index]) - float(out[0, yaw_index])) / (2.0 * math.pi)
    if math.isfinite(turns):  # Python's round halves to even, as np.round does
        turns = float(round(turns))
    out[:, yaw_index] += 2.0 * math.pi * turns
    out[0] = state0
    return out, held


def first_command(t_s: float, inputs: np.ndarray) -> Command:
    """The command a plan applies now: its first row of inputs."""
    return Command(t_s=t_s, accel_mps2=float(inputs[0, INPUT["accel_mps2"]]),
                   steer_rad=float(inputs[0, INPUT["steer_rad"]]))
