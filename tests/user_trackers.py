"""Trackers as a user might write them, good and broken, loaded by import path
(``tests.user_trackers:Name``) in the plug-in tests and the bad-input table."""

from __future__ import annotations

import dataclasses
import os
import sys
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from cosim.core.config_fields import setting
from cosim.core.records import Command, Estimate, Plan


def _plan(t_s: float, accel_mps2: float, steer_rad: float) -> Plan:
    return Plan(t_s=t_s, dt_s=0.05, state_names=("vx_mps",), states=np.zeros((2, 1)),
                input_names=("accel_mps2", "steer_rad"),
                inputs=np.array([[accel_mps2, steer_rad]]), cost=0.0, solve_time_s=0.0,
                iterations=0, status="ok", success=True, fallback=False)


class Straight:
    """Holds the wheel straight and the speed; misbehaves from ``params.fail_at_s`` on."""

    @dataclass(frozen=True)
    class Params:
        fail_at_s: float = setting(1e9, low=0.0, high=1e9, doc="when to misbehave")
        sleep_s: float = setting(0.0, low=0.0, high=10.0, doc="how long a step takes")

    def __init__(self, params: Straight.Params, config: Any) -> None:
        self.params = params

    def failing(self, t_s: float) -> bool:
        return t_s >= self.params.fail_at_s

    def step(self, t_s: float, estimate: Estimate, reference: Any) -> tuple[Command, Plan]:
        return Command(t_s, 0.0, 0.0), _plan(t_s, 0.0, 0.0)


class Raising(Straight):
    def step(self, t_s: float, estimate: Estimate, reference: Any) -> tuple[Command, Plan]:
        if self.failing(t_s):
            raise ZeroDivisionError("the user's bug")
        return super().step(t_s, estimate, reference)


class NanSteer(Straight):
    def step(self, t_s: float, estimate: Estimate, reference: Any) -> tuple[Command, Plan]:
        steer = float("nan") if self.failing(t_s) else 0.0
        return Command(t_s, 0.0, steer), _plan(t_s, 0.0, steer)


class Slow(Straight):
    def step(self, t_s: float, estimate: Estimate, reference: Any) -> tuple[Command, Plan]:
        if self.failing(t_s):
            time.sleep(self.params.sleep_s)
        return super().step(t_s, estimate, reference)


class WrongReturn(Straight):
    def step(self, t_s: float, estimate: Estimate, reference: Any) -> Any:
        return (Command(t_s, 0.0, 0.0),)  # a tuple without its plan


class NoParams:
    """No schema: gets ``tracker.params`` as a plain mapping."""

    def __init__(self, params: dict[str, Any], config: Any) -> None:
        self.gain = float(params.get("gain", 0.0))

    def step(self, t_s: float, estimate: Estimate, reference: Any) -> tuple[Command, Plan]:
        accel = self.gain * (20.0 - estimate["vx_mps"])
        return Command(t_s, accel, 0.0), _plan(t_s, accel, 0.0)


class NoStep:
    def __init__(self, params: Any, config: Any) -> None:
        pass

    def steer(self) -> float:
        return 0.0


not_a_class = 3


class Exiting(Straight):
    """Calls ``sys.exit`` from ``fail_at_s`` on, as a script's habit might."""

    def step(self, t_s: float, estimate: Estimate, reference: Any) -> tuple[Command, Plan]:
        if self.failing(t_s):
            sys.exit(0)
        return super().step(t_s, estimate, reference)


class HardExit(Straight):
    """Ends its process from ``fail_at_s`` on with ``os._exit``: nothing can catch it, so a
    sweep worker dies under its run."""

    def step(self, t_s: float, estimate: Estimate, reference: Any) -> tuple[Command, Plan]:
        if self.failing(t_s):
            os._exit(7)
        return super().step(t_s, estimate, reference)


class StringAccel(Straight):
    def step(self, t_s: float, estimate: Estimate, reference: Any) -> tuple[Command, Plan]:
        return Command(t_s, "fast", 0.0), _plan(t_s, 0.0, 0.0)  # type: ignore[arg-type]


class ArraySteer(Straight):
    def step(self, t_s: float, estimate: Estimate, reference: Any) -> tuple[Command, Plan]:
        steer = np.array([0.1, 0.2])
        return Command(t_s, 0.0, steer), _plan(t_s, 0.0, 0.0)  # type: ignore[arg-type]


class BadPlanStates(Straight):
    def step(self, t_s: float, estimate: Estimate, reference: Any) -> tuple[Command, Plan]:
        plan = dataclasses.replace(_plan(t_s, 0.0, 0.0), states=np.zeros((2, 3)))
        return Command(t_s, 0.0, 0.0), plan


class ExitsAtOnce(Straight):
    """Calls ``sys.exit`` at its first step after 0.1 s (no params needed: for compare)."""

    def step(self, t_s: float, estimate: Estimate, reference: Any) -> tuple[Command, Plan]:
        if t_s >= 0.1:
            sys.exit("the user's script gave up")
        return super().step(t_s, estimate, reference)


class CommandOnly:
    """Returns a Command alone (no plan): speeds up a little, wheel straight."""

    def __init__(self, params: Any, config: Any) -> None:
        del params, config

    def step(self, t_s: float, estimate: Estimate, reference: Any) -> Command:
        return Command(t_s, 1.0, 0.0)


class WideSteer(Straight):
    """Commands 20 rad of steering (a unit slip, degrees for radians) from ``fail_at_s`` on."""

    def step(self, t_s: float, estimate: Estimate, reference: Any) -> tuple[Command, Plan]:
        if self.failing(t_s):
            return Command(t_s, 0.0, 20.0), _plan(t_s, 0.0, 20.0)
        return super().step(t_s, estimate, reference)
