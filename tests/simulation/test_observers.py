"""The loop's shape: one function orders a step's phases, observers only look."""

from __future__ import annotations

import dataclasses
import warnings

import pytest

from cosim.log.recorder import NoLog
from cosim.simulation.observers import LogInstant, Observer
from cosim.simulation.run_control import StopRequest, WallClock
from cosim.simulation.runner import RunState, finish_run
from cosim.simulation.scenario_config import load_config

MAX_RUN_ATTRIBUTES = 15
"""The run object holds the simulation, its clock and its observers: no more."""


class _Spy(Observer):
    """Writes down the points it is called at, with the simulated time."""

    def __init__(self) -> None:
        self.calls: list[tuple[str, float]] = []

    def logged(self, instant: LogInstant) -> None:
        self.calls.append(("logged", instant.t_s))

    def sensed(self, t_s, measurement) -> None:
        self.calls.append(("sensed", t_s))

    def fused(self, t_s, measurement, update) -> None:
        self.calls.append(("fused", t_s))

    def controlled(self, t_s, plan, command, step_time_s) -> None:
        self.calls.append(("controlled", t_s))

    def actuated(self, t_s, command, actuator) -> None:
        self.calls.append(("actuated", t_s))

    def finished(self, values) -> None:
        self.calls.append(("finished", float("nan")))


def _run(overrides: list[str], spy: _Spy | None = None) -> dict[str, object]:
    config = dataclasses.replace(load_config("lane-change", overrides=overrides), seed=3)
    state = RunState(config, NoLog())
    if spy is not None:
        state.observers = (*state.observers, spy)
    state.loop(StopRequest(), None)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        values = finish_run(state, WallClock(0.0, 0.0), True, "", "")
    return {k: v for k, v in values.items() if not k.endswith(("_ms_p50", "_ms_p99",
                                                              "_ms_max", "_ms_mean"))
            and k not in ("wall_time_s", "realtime_factor", "setup_time_s")}


def test_the_run_object_holds_at_most_15_attributes() -> None:
    state = RunState(load_config("lane-change"), NoLog())
    assert len(vars(state)) <= MAX_RUN_ATTRIBUTES, sorted(vars(state))


def test_a_step_takes_its_phases_in_order_and_an_observer_changes_nothing() -> None:
    """With ``plant.actuator_delay_s`` 0 the first command reaches the plant in the step
    it is planned: log, sensors, their fusion, control, actuation, in that order."""
    spy = _Spy()
    overrides = ["plant.actuator_delay_s=0", "sim.duration_s=1"]
    watched = _run(overrides, spy)
    first = [name for name, t_s in spy.calls if t_s == 0.0]
    order = ["logged", "sensed", "fused", "controlled", "actuated"]
    assert [first.index(name) for name in order] == sorted(first.index(n) for n in order)
    assert spy.calls[-1][0] == "finished"
    # 0 .. 0.95 s at 20 Hz: the last step (1 s) is logged and sensed, the run ends there
    assert sum(name == "controlled" for name, _ in spy.calls) == 20
    assert watched == _run(overrides)


@pytest.mark.parametrize("pause_at_control", [False, True])
def test_a_run_paused_at_each_control_instant_is_the_same_run(pause_at_control: bool) -> None:
    """The Gymnasium environment pauses :meth:`advance` at each control instant and
    resumes it: the same steps as the run's own loop."""
    config = dataclasses.replace(load_config("lane-change", overrides=["sim.duration_s=2"]),
                                 seed=5)
    state = RunState(config, NoLog())
    if pause_at_control:
        k, ended = state.advance(0, pause_at_control=True)
        pauses = 0
        while not ended:
            pauses += 1
            k, ended = state.advance(k, observed=True, pause_at_control=True)
        assert pauses == 40  # 0 .. 1.95 s at 20 Hz: the run ends at 2 s before control
    else:
        state.loop(StopRequest(), None)
    truth = state.truth
    reference = RunState(config, NoLog())
    reference.loop(StopRequest(), None)
    assert truth.to_message() == reference.truth.to_message()
