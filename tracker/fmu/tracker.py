"""``--tracker fmu:PATH.fmu``: a co-simulation FMU (FMI 2 or FMI 3) as the path tracker.

Every control period ``h = sim.control_period_s`` the runner calls :meth:`FmuTracker.step`
at ``t_k = k h``: the inputs the FMU declares are computed from the estimate and the
reference (:mod:`tracker.fmu.signals`), set, the FMU advances ``doStep(t_k, h)`` and its
outputs ``steer_rad`` and ``accel_mps2`` become the command applied from ``t_k`` (through
the actuator delay, like every tracker's). The FMU's communication step is thus the control
period: the FMU's clock runs with the simulation's, and what it computes over
``[t_k, t_k + h]`` from inputs held at their ``t_k`` values is what the car gets for that
period (for a static law, ``f(u(t_k))``). The FMU is the whole controller: cosim does not
predict the estimate over the actuator delay for it; it only clips the command to the
tracker's bounds (``tracker.max_steer_rad``, ``tracker.accel_min_mps2`` ..
``accel_max_mps2``), as the vehicle's interface would.

A failing FMU ends the run, with its log kept and ``completed: false``
(:class:`cosim.core.exceptions.TrackerFault`, the reason naming the FMU): an FMI call that
returns an error (the FMU's own last log message quoted), a non-finite output, the FMU's
request to terminate, a step longer than ``tracker.step_budget_s``. A non-finite estimate
is not passed on: the step commands a safe stop (steering held,
``tracker.safe_stop_accel_mps2``), counted as a fallback, while the FMU steps on with its
last inputs so that its clock stays the simulation's.
"""

from __future__ import annotations

import math
import time

import numpy as np

from cosim.core.exceptions import TrackerFault
from cosim.core.records import Command, Estimate, Plan
from tracker.config import TrackerConfig
from tracker.fmu.description import FmuDescription, describe
from tracker.fmu.signals import InputFeed
from tracker.fmu.slave import FmuSlave
from tracker.paths.reference_path import ReferencePath

PLAN_STATES = ("vx_mps",)
"""The plan's one state: the FMU predicts nothing cosim could read."""
PLAN_INPUTS = ("accel_mps2", "steer_rad")


class FmuTracker:
    """An FMU stepped once per control period (module docstring)."""

    def __init__(self, config: TrackerConfig, control_period_s: float,
                 description: FmuDescription | None = None) -> None:
        self.name = config.name
        self.config = config
        self.period_s = control_period_s
        self.description = description if description is not None else \
            describe(config.name, config.fmu, control_period_s)
        self.feed = InputFeed(tuple(v.name for v in self.description.inputs),
                              config.fmu.preview_spacing_m)
        self.slave = FmuSlave(self.description)
        self._steps = 0
        self._inputs: list[float] = [0.0] * len(self.description.inputs)
        self._steer_rad = 0.0

    def reset(self) -> None:
        """A fresh instance at t = 0 (a new run)."""
        self.slave.close()
        self.slave = FmuSlave(self.description)
        self.feed.reset()
        self._steps = 0
        self._steer_rad = 0.0

    def close(self) -> None:
        """Free the FMU and remove its extracted files."""
        self.slave.close()

    def step(self, t_s: float, estimate: Estimate,
             reference: ReferencePath) -> tuple[Command, Plan]:
        began = time.perf_counter()
        fmu_t_s = self._steps * self.period_s
        if abs(t_s - fmu_t_s) > 0.5 * self.period_s:
            raise TrackerFault(f"tracker {self.name!r} stepped at t = {t_s:.3f} s: expected "
                               f"one step per control period (the FMU is at {fmu_t_s:.3f} s)")
        finite = bool(np.all(np.isfinite(estimate.mean)))
        if finite:
            self._inputs = self.feed.values(t_s, estimate, reference)
        steer, accel = self._do_step(t_s, fmu_t_s)
        elapsed_s = time.perf_counter() - began
        if elapsed_s > self.config.step_budget_s:
            raise TrackerFault(f"tracker {self.name!r} took {elapsed_s:.3f} s for the step at "
                               f"t = {t_s:.3f} s: more than tracker.step_budget_s = "
                               f"{self.config.step_budget_s:g} s")
        cfg = self.config
        if not finite:
            command = Command(t_s, cfg.safe_stop_accel_mps2, self._steer_rad)
            return command, self._plan(t_s, estimate, command, elapsed_s, "non_finite_estimate")
        command = Command(t_s, float(np.clip(accel, cfg.accel_min_mps2, cfg.accel_max_mps2)),
                          float(np.clip(steer, -cfg.max_steer_rad, cfg.max_steer_rad)))
        self._steer_rad = command.steer_rad
        clipped = (command.accel_mps2, command.steer_rad) != (accel, steer)
        return command, self._plan(t_s, estimate, command, elapsed_s,
                                   "clipped" if clipped else "ok")

    def _do_step(self, t_s: float, fmu_t_s: float) -> tuple[float, float]:
        """One ``doStep`` from the FMU's own time; a failure is a :class:`TrackerFault`."""
        try:
            steer, accel = self.slave.step(fmu_t_s, self.period_s, self._inputs)
        except Exception as error:  # fmpy raises plain Exceptions (FMICallException ...)
            said = self.slave.last_message()
            raise TrackerFault(f"tracker {self.name!r} failed at t = {t_s:.3f} s: {error}"
                               + (f" (the FMU said: {said})" if said else "")) from error
        self._steps += 1
        if not (math.isfinite(steer) and math.isfinite(accel)):
            raise TrackerFault(f"tracker {self.name!r} returned a non-finite output at "
                               f"t = {t_s:.3f} s (steer_rad = {steer}, accel_mps2 = {accel})")
        return steer, accel

    def _plan(self, t_s: float, estimate: Estimate, command: Command, elapsed_s: float,
              status: str) -> Plan:
        ok = status in ("ok", "clipped")
        speed = estimate["vx_mps"] if "vx_mps" in estimate else float("nan")
        return Plan(t_s=t_s, dt_s=self.period_s, state_names=PLAN_STATES,
                    states=np.array([[speed]]), input_names=PLAN_INPUTS,
                    inputs=np.array([[command.accel_mps2, command.steer_rad]]),
                    cost=float("nan"), solve_time_s=elapsed_s, iterations=0, status=status,
                    success=ok, fallback=not ok)
