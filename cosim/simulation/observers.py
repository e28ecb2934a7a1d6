"""What looks at a run without taking part in it: the points of a step where observers are called.

The loop (:meth:`cosim.simulation.runner._Run.advance`) simulates: the plant, the sensors,
the filter, the tracker, the actuator delay line and the disturbances. Everything that only
looks (the log, the metrics, the outcome and course monitors, the requirements' signals)
is an observer, called at named points of a step in the order the step takes them, in the
manner of the hooks around dm_control's ``Environment.step``:

============== ======================================================================
``logged``     a log instant: the truth and the estimate at the same time stamp
``sensed``     a sensor delivered a measurement (after its faults)
``fused``      the filter took (or gated) that measurement: its :class:`UpdateResult`
``controlled`` the tracker planned: its plan, its command and the time it took
``actuated``   a command left the delay line: the wheel torques it became
``disturbed``  an unmeasured disturbance was applied to the plant
``event``      something happened worth a line on ``/events`` (an outcome event, a fault)
``finished``   the run's metrics, once, at its end
============== ======================================================================

An observer changes nothing that is simulated: a run with or without any of them gives the
same numbers bit for bit (``tests/simulation/test_observers.py``). A run without a log
simply has no log observer. :class:`Observer` is the do-nothing base: an observer
overrides the points it needs.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

if TYPE_CHECKING:
    from cosim.core.records import (
        ActuatorCommand,
        Command,
        Estimate,
        Measurement,
        Plan,
        VehicleState,
    )
    from cosim.plant.disturbances import YawRateChange
    from cosim.simulation.outcome import Event
    from estimation.update_result import UpdateResult


@dataclass(frozen=True, slots=True)
class LogInstant:
    """What a log instant shows: the truth and the estimate at the same time stamp."""

    k: int
    """The physics step."""
    t_s: float
    truth: VehicleState
    estimate: Estimate
    """The filter's estimate predicted to ``truth.t_s`` without changing the filter."""
    scene: bool
    """A Foxglove scene instant too (every ``sim.scene_period_s``)."""
    tyre_loads_n: tuple[float, ...] | None
    """The tyres' vertical loads, where the plant reports them (wheel-lift detection)."""


class RunObserver(Protocol):
    """The points of a step an observer is called at (module docstring)."""

    def logged(self, instant: LogInstant) -> None: ...

    def sensed(self, t_s: float, measurement: Measurement) -> None: ...

    def fused(self, t_s: float, measurement: Measurement, update: UpdateResult) -> None: ...

    def controlled(self, t_s: float, plan: Plan, command: Command,
                   step_time_s: float) -> None: ...

    def actuated(self, t_s: float, command: Command, actuator: ActuatorCommand) -> None: ...

    def disturbed(self, t_s: float, change: YawRateChange) -> None: ...

    def event(self, event: Event) -> None: ...

    def finished(self, values: dict[str, float | int | bool | str]) -> None: ...


class Observer:
    """An observer that looks at nothing: subclasses override the points they need."""

    def logged(self, instant: LogInstant) -> None:
        del instant

    def sensed(self, t_s: float, measurement: Measurement) -> None:
        del t_s, measurement

    def fused(self, t_s: float, measurement: Measurement, update: UpdateResult) -> None:
        del t_s, measurement, update

    def controlled(self, t_s: float, plan: Plan, command: Command,
                   step_time_s: float) -> None:
        del t_s, plan, command, step_time_s

    def actuated(self, t_s: float, command: Command, actuator: ActuatorCommand) -> None:
        del t_s, command, actuator

    def disturbed(self, t_s: float, change: YawRateChange) -> None:
        del t_s, change

    def event(self, event: Event) -> None:
        del event

    def finished(self, values: dict[str, float | int | bool | str]) -> None:
        del values
