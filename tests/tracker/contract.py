"""Checks every NMPC tracker's closed-loop run must pass, whatever its model."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from cosim.core.records import Command, Plan
from tracker.config import TrackerConfig


def assert_every_solve_succeeded(plans: Sequence[Plan], config: TrackerConfig) -> None:
    assert all(plan.success and not plan.fallback for plan in plans)
    assert all(np.isfinite(plan.cost) for plan in plans)
    assert all(0 < plan.iterations <= config.max_iterations for plan in plans)


def assert_commands_within_bounds(commands: Sequence[Command], config: TrackerConfig) -> None:
    steer = np.array([c.steer_rad for c in commands])
    accel = np.array([c.accel_mps2 for c in commands])
    assert np.all(np.abs(steer) <= config.max_steer_rad)
    assert np.all(accel >= config.accel_min_mps2)
    assert np.all(accel <= config.accel_max_mps2)
    # The first command is rate-limited against the zero command of reset().
    steer_steps = np.abs(np.diff(np.concatenate(([0.0], steer))))
    assert np.all(steer_steps <= config.max_steer_rate_radps * config.dt_s + 1e-9)


def assert_reaches_speed(speed_mps: np.ndarray, target_mps: float, within_s: float,
                         step_s: float = 0.002, tolerance_mps: float = 0.2) -> None:
    """The speed (one sample per physics step) comes within 0.1 m/s of ``target_mps`` by
    ``within_s`` and then stays within ``tolerance_mps`` of it."""
    reached = np.flatnonzero(speed_mps > target_mps - 0.1)
    assert reached.size > 0
    assert reached[0] * step_s < within_s
    assert np.max(np.abs(speed_mps[reached[0]:] - target_mps)) < tolerance_mps


def assert_tracks_the_lane_change(cte_m: np.ndarray, final_x_m: float, cte_max_m: float,
                                  settled_cte_m: float = 0.005) -> None:
    """The stretched double lane change on a controller's own model: the cross-track error
    stays under ``cte_max_m``, the car goes through the whole manoeuvre (it ends near
    x = 295 m), and it has converged to the path on the straight after it (the last second,
    500 physics steps of 2 ms, under ``settled_cte_m``)."""
    assert np.max(np.abs(cte_m)) < cte_max_m
    assert final_x_m > 250.0
    assert np.max(np.abs(cte_m[-500:])) < settled_cte_m
