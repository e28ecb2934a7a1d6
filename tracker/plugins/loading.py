"""Trackers from outside cosim: load, check and guard a user's tracker class.

``tracker.name`` names a class by import path (``my_pkg.my_module:MyTracker``) or by an
entry point of the group ``cosim.trackers`` (:mod:`cosim.core.plugins`). The class must have a
``step(t_s, estimate, reference) -> (Command, Plan)`` method (the
:class:`tracker.protocol.Tracker` protocol) and is built as ``cls(params, config)``:

- ``params``: the scenario's ``tracker.params`` section (``--set tracker.params.gain=2``).
  A class that declares a schema, a dataclass as its attribute ``Params``, gets an instance
  of it, validated by :func:`cosim.core.config_fields.from_dict` (unknown keys, types and the
  ``setting`` bounds are checked, errors name ``tracker.params.KEY``); otherwise the plain
  mapping.
- ``config``: the whole :class:`tracker.config.TrackerConfig` (the belief ``model``, the
  steering and acceleration bounds, ``dt_s``).

The runner cannot vouch for such code, so each step goes through :class:`GuardedTracker`:
a step that raises (any exception, ``SystemExit`` included: only ``KeyboardInterrupt`` goes
on, as the user's interrupt), returns a non-finite command or overruns
``tracker.step_budget_s`` ends the run (``completed: false``, the log kept) with a reason
naming the tracker; a step that returns something other than ``(Command, Plan)``, or a
field of either of the wrong type or shape (:mod:`tracker.plugins.checks`), is refused as a
broken interface (exit code 2), naming the field.
"""

from __future__ import annotations

import dataclasses
import time
import traceback
import warnings
from dataclasses import dataclass
from typing import Any

from cosim.core.config_fields import from_dict, to_dict
from cosim.core.exceptions import ConfigError, PluginError, TrackerFault
from cosim.core.plugins import load_object
from cosim.core.records import Command, Estimate, Plan
from tracker.config import PLUGIN_GROUP, TrackerConfig
from tracker.paths.reference_path import ReferencePath
from tracker.plugins.checks import check_step_result
from tracker.protocol import Resettable, Tracker

GROUP = PLUGIN_GROUP
"""Entry-point group of tracker plug-ins."""


def tracker_class(name: str) -> type:
    """The class ``name`` refers to, checked to be a class with a ``step`` method."""
    cls = load_object(name, GROUP, "tracker.name")
    if not isinstance(cls, type):
        raise PluginError(f"tracker.name = {name!r}: is a {type(cls).__name__}: expected a "
                          "tracker class")
    if not callable(getattr(cls, "step", None)):
        raise PluginError(f"tracker.name = {name!r}: class {cls.__name__} has no step "
                          "method: expected step(t_s, estimate, reference) -> (Command, Plan)")
    return cls


def plugin_params(cls: type, params: dict[str, Any]) -> Any:
    """``tracker.params`` as the class's ``Params`` dataclass (validated), or the mapping."""
    schema = getattr(cls, "Params", None)
    if schema is None:
        return dict(params)
    if not dataclasses.is_dataclass(schema):
        raise PluginError(f"{cls.__module__}:{cls.__qualname__}.Params: expected a dataclass "
                          "(the schema of tracker.params)")
    return from_dict(schema, params, "tracker.params")


def resolved_params(config: TrackerConfig) -> dict[str, Any]:
    """``tracker.params`` with the schema's defaults filled in (as given, without a schema):
    what a sweep varies and calls nominal."""
    params = plugin_params(tracker_class(config.name), config.params)
    return to_dict(params) if dataclasses.is_dataclass(params) else dict(params)


def check_plugin(config: TrackerConfig) -> None:
    """Load and check the plug-in ``config.name`` (and its params) before any run starts."""
    plugin_params(tracker_class(config.name), config.params)


def make_plugin_tracker(config: TrackerConfig) -> Tracker:
    """Build the plug-in ``config.name`` with its params, guarded."""
    cls = tracker_class(config.name)
    try:
        tracker = cls(plugin_params(cls, config.params), config)
    except (ConfigError, KeyboardInterrupt):
        raise
    except BaseException as error:  # noqa: BLE001 - user code: SystemExit included
        raise PluginError(f"tracker.name = {config.name!r}: {cls.__name__}(params, config) "
                          f"raised {type(error).__name__}: {error}") from None
    return GuardedTracker(config.name, tracker, config.step_budget_s,
                          CommandBounds(config.max_steer_rad, config.accel_min_mps2,
                                        config.accel_max_mps2))


def _where(error: BaseException) -> str:
    """`` (file.py:12, in step)``: the innermost frame of the traceback, the line that
    raised, in the user's code or below it."""
    frames = traceback.extract_tb(error.__traceback__)
    if not frames:
        return ""
    last = frames[-1]
    return f" ({last.filename}:{last.lineno}, in {last.name})"


class TrackerCommandClipped(UserWarning):
    """A plug-in tracker commanded beyond the tracker's bounds (:class:`GuardedTracker`)."""


@dataclass(frozen=True)
class CommandBounds:
    """The tracker's bounds (``tracker.max_steer_rad``, ``tracker.accel_min_mps2``,
    ``tracker.accel_max_mps2``) a plug-in's command is clipped to."""

    max_steer_rad: float
    accel_min_mps2: float
    accel_max_mps2: float


class GuardedTracker:
    """A user's tracker whose failures end the run with a reason instead of a traceback.

    Its command is clipped to the tracker's bounds, as an FMU tracker's is, and the first
    command beyond them is said once a run (:class:`TrackerCommandClipped`): 20 rad of
    steering used to run on without a word, the plant clipping it to its own limit."""

    def __init__(self, name: str, tracker: Any, budget_s: float,
                 bounds: CommandBounds | None = None) -> None:
        self.name = name
        self._tracker = tracker
        self._budget_s = budget_s
        self._bounds = bounds
        self._warned = False

    def reset(self) -> None:
        self._warned = False
        if isinstance(self._tracker, Resettable):
            self._tracker.reset()

    def _bounded(self, t_s: float, command: Command) -> Command:
        bounds = self._bounds
        if bounds is None:
            return command
        steer = min(max(command.steer_rad, -bounds.max_steer_rad), bounds.max_steer_rad)
        accel = min(max(command.accel_mps2, bounds.accel_min_mps2), bounds.accel_max_mps2)
        if (steer, accel) == (command.steer_rad, command.accel_mps2):
            return command
        if not self._warned:
            self._warned = True
            beyond = (f"steer_rad = {command.steer_rad:.4g}, beyond +-tracker.max_steer_rad = "
                      f"{bounds.max_steer_rad:.4g}" if steer != command.steer_rad else
                      f"accel_mps2 = {command.accel_mps2:.4g}, outside [tracker.accel_min_mps2,"
                      f" tracker.accel_max_mps2] = [{bounds.accel_min_mps2:g}, "
                      f"{bounds.accel_max_mps2:g}]")
            warnings.warn(f"tracker {self.name!r} commanded {beyond} at t = {t_s:.3f} s: "
                          "clipped to the bounds (said once a run)", TrackerCommandClipped,
                          stacklevel=2)
        return dataclasses.replace(command, steer_rad=steer, accel_mps2=accel)

    def step(self, t_s: float, estimate: Estimate,
             reference: ReferencePath) -> tuple[Command, Plan]:
        start_s = time.perf_counter()
        try:
            result = self._tracker.step(t_s, estimate, reference)
        except KeyboardInterrupt:
            raise
        except BaseException as error:  # noqa: BLE001 - user code: SystemExit included
            if isinstance(error, SystemExit):  # its text is only the exit code again
                what, detail = f"called sys.exit({error.code!r})", ""
            else:
                what, detail = f"raised {type(error).__name__}", f": {error}" if str(error) else ""
            raise TrackerFault(
                f"tracker {self.name!r} {what} at t = {t_s:.3f} s{detail}{_where(error)}",
                "".join(traceback.format_exception(error))) from error
        elapsed_s = time.perf_counter() - start_s
        command, plan = check_step_result(self.name, t_s, result)
        if elapsed_s > self._budget_s:
            raise TrackerFault(f"tracker {self.name!r} took {elapsed_s:.3f} s for the step at "
                               f"t = {t_s:.3f} s: more than tracker.step_budget_s = "
                               f"{self._budget_s:g} s")
        return self._bounded(t_s, command), plan
