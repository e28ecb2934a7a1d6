"""What a tracker from outside cosim returns, checked field by field before the run uses it.

A user's ``step`` must return ``(Command, Plan)`` (:mod:`cosim.core.records`). The records are
plain dataclasses, so nothing stops a plug-in from putting a string, an array or ``None``
into a field; the runner would then fail far from the cause (a ``TypeError`` in the
actuator, a ``ValueError`` while logging). :func:`check_step_result` checks every field of
both records against its declared type and shape and raises one
:class:`~cosim.core.exceptions.PluginError` naming the tracker, the class, the field, the
value and what was expected, e.g.::

    tracker.name = 'my_pkg:Mine': step returned Command.accel_mps2 = 'fast' (str) at
    t = 0.050 s: expected a finite number

A non-finite command is not an interface error but a failed step
(:class:`~cosim.core.exceptions.TrackerFault`: the run ends ``completed: false``), as before.
"""

from __future__ import annotations

import math
import numbers
from typing import Any

import numpy as np

from cosim.core.exceptions import PluginError, TrackerFault
from cosim.core.records import Command, Plan
from cosim.core.yaml_io import shown

COMMAND_NUMBERS = ("t_s", "accel_mps2", "steer_rad")
"""Fields of :class:`Command`, each a real number."""

PLAN_NUMBERS = ("t_s", "dt_s", "cost", "solve_time_s")
"""Real-number fields of :class:`Plan` (``cost`` may be NaN: a failed solve has none)."""

PLAN_FLAGS = ("success", "fallback", "speed_reduced")
"""True/false fields of :class:`Plan`."""


class _Field:
    """Names one field of a returned record in messages."""

    def __init__(self, tracker: str, t_s: float, record: str) -> None:
        self.tracker, self.t_s, self.record = tracker, t_s, record

    def error(self, name: str, value: Any, expected: str, seen: str = "") -> PluginError:
        """``seen`` describes the value instead of its repr and type (an array's shape)."""
        seen = seen or f"{shown(value)} ({type(value).__name__})"
        return PluginError(
            f"tracker.name = {self.tracker!r}: step returned {self.record}.{name} = {seen} "
            f"at t = {self.t_s:.3f} s: expected {expected}")


def _is_real(value: Any) -> bool:
    """A real number: Python or numpy, not a bool (``True`` is an int in Python)."""
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


def _names(field: _Field, name: str, value: Any) -> tuple[str, ...]:
    if not (isinstance(value, tuple) and all(isinstance(v, str) for v in value)):
        raise field.error(name, value, "a tuple of names (str)")
    return value


def _matrix(field: _Field, name: str, value: Any, columns: int, names: str) -> None:
    if not isinstance(value, np.ndarray):
        raise field.error(name, value, f"a 2-D numpy array with one column per {names}")
    if value.ndim != 2 or value.shape[1] != columns:
        raise field.error(name, value, f"shape (rows, {columns}), one column per {names}",
                          f"an array of shape {value.shape}")
    if not (np.issubdtype(value.dtype, np.integer) or np.issubdtype(value.dtype, np.floating)):
        raise field.error(name, value, "an array of real numbers",
                          f"an array of {value.dtype}")


def check_command(tracker: str, t_s: float, command: Command) -> None:
    """Every field of ``command`` a real number; then finite (else :class:`TrackerFault`)."""
    field = _Field(tracker, t_s, "Command")
    for name in COMMAND_NUMBERS:
        value = getattr(command, name)
        if not _is_real(value):
            raise field.error(name, value, "a finite number")
    if not (math.isfinite(command.accel_mps2) and math.isfinite(command.steer_rad)):
        raise TrackerFault(f"tracker {tracker!r} returned a non-finite command at "
                           f"t = {t_s:.3f} s (accel_mps2 = {command.accel_mps2}, "
                           f"steer_rad = {command.steer_rad})")


def check_plan(tracker: str, t_s: float, plan: Plan) -> None:
    """Every field of ``plan`` of its declared type; the arrays one column per name."""
    field = _Field(tracker, t_s, "Plan")
    for name in PLAN_NUMBERS:
        value = getattr(plan, name)
        if not _is_real(value):
            raise field.error(name, value, "a number")
    for name in ("t_s", "dt_s", "solve_time_s"):
        value = getattr(plan, name)
        if not (math.isfinite(value) and value >= 0.0):
            raise field.error(name, value, "a finite number >= 0")
    if not (isinstance(plan.iterations, numbers.Integral)
            and not isinstance(plan.iterations, (bool, np.bool_)) and plan.iterations >= 0):
        raise field.error("iterations", plan.iterations, "a whole number >= 0")
    if not isinstance(plan.status, str):
        raise field.error("status", plan.status, "a str (the solver's status)")
    for name in PLAN_FLAGS:
        value = getattr(plan, name)
        if not isinstance(value, (bool, np.bool_)):
            raise field.error(name, value, "true or false (bool)")
    states = _names(field, "state_names", plan.state_names)
    inputs = _names(field, "input_names", plan.input_names)
    _matrix(field, "states", plan.states, len(states), "name in state_names")
    _matrix(field, "inputs", plan.inputs, len(inputs), "name in input_names")


def check_step_result(tracker: str, t_s: float, result: Any) -> tuple[Command, Plan]:
    """``result`` as ``(Command, Plan)``, every field checked (module docstring); a
    :class:`Command` alone gets :meth:`Plan.of_command` as its plan."""
    if isinstance(result, Command):
        check_command(tracker, t_s, result)
        return result, Plan.of_command(result)
    if not (isinstance(result, tuple) and len(result) == 2
            and isinstance(result[0], Command) and isinstance(result[1], Plan)):
        raise PluginError(f"tracker.name = {tracker!r}: step returned {_describe(result)}: "
                          "expected a Command, or a tuple (Command, Plan) (cosim.Command, "
                          "cosim.Plan)")
    command, plan = result
    check_plan(tracker, t_s, plan)
    check_command(tracker, t_s, command)
    return command, plan


def _describe(value: object) -> str:
    if isinstance(value, tuple):
        return "(" + ", ".join(type(v).__name__ for v in value) + ")"
    return type(value).__name__
