"""Checks every NMPC tracker's closed-loop run must pass, whatever its model."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from cosim.records import Command, Plan
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
