"""The ``open-loop`` tracker: a steering profile in time and a proportional speed hold.

It ignores the reference path: it exists to drive the plant through the open-loop handling
manoeuvres of :mod:`tracker.manoeuvre` (and so through the same runner, sensors, estimator
and log as any closed-loop run).
"""

from __future__ import annotations

import time

import numpy as np

from cosim.core.records import Command, Estimate, Plan
from tracker.config import TrackerConfig
from tracker.manoeuvre import ManoeuvreConfig
from tracker.paths.reference_path import ReferencePath

STATE_NAMES = ("vx_mps",)
INPUT_NAMES = ("accel_mps2", "steer_rad")


class OpenLoopTracker:
    """Steer ``manoeuvre.steer_at(t)``; accelerate ``k (v_set - v_est)`` within the bounds."""

    def __init__(self, config: TrackerConfig, manoeuvre: ManoeuvreConfig) -> None:
        self._config = config
        self._manoeuvre = manoeuvre

    def reset(self) -> None:
        """Stateless: nothing to reset."""

    def step(self, t_s: float, estimate: Estimate,
             reference: ReferencePath) -> tuple[Command, Plan]:
        del reference  # open loop: the path is not followed
        start = time.perf_counter()
        manoeuvre, config = self._manoeuvre, self._config
        speed_error_mps = manoeuvre.speed_mps - estimate["vx_mps"]
        accel = float(np.clip(manoeuvre.speed_gain_1ps * speed_error_mps,
                              config.accel_min_mps2, config.accel_max_mps2))
        steer = float(np.clip(manoeuvre.steer_at(t_s), -config.max_steer_rad,
                              config.max_steer_rad))
        command = Command(t_s, accel, steer)
        plan = Plan(
            t_s=t_s, dt_s=0.0, state_names=STATE_NAMES,
            states=np.array([[estimate["vx_mps"]]]), input_names=INPUT_NAMES,
            inputs=np.array([[accel, steer]]), cost=0.0,
            solve_time_s=time.perf_counter() - start, iterations=0, status="open-loop",
            success=True, fallback=False,
        )
        return command, plan
