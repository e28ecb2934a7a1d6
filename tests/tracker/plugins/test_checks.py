"""Every field of a plug-in's ``(Command, Plan)`` is checked, and a bad one is named."""

from __future__ import annotations

import dataclasses
import warnings
from pathlib import Path

import numpy as np
import pytest

from cosim.core.exceptions import PluginError, TrackerFault
from cosim.core.records import Command, Plan
from cosim.log.reader import iter_messages
from cosim.simulation.runner import run
from cosim.simulation.scenario_config import UnitHint, load_config
from tracker.plugins.checks import check_step_result
from tracker.plugins.loading import TrackerCommandClipped


def _good() -> tuple[Command, Plan]:
    plan = Plan(t_s=0.5, dt_s=0.05, state_names=("vx_mps", "y_m"), states=np.zeros((3, 2)),
                input_names=("accel_mps2",), inputs=np.zeros((2, 1)), cost=1.0,
                solve_time_s=0.001, iterations=3, status="ok", success=True, fallback=False)
    return Command(0.5, 0.0, 0.0), plan


BAD_COMMAND = {"t_s": "now", "accel_mps2": "fast", "steer_rad": np.array([0.1, 0.2])}
BAD_PLAN = {
    "t_s": None, "dt_s": -0.05, "state_names": ["vx_mps", "y_m"], "states": "nope",
    "input_names": ("accel_mps2", 3), "inputs": np.zeros((2, 4)), "cost": "cheap",
    "solve_time_s": float("nan"), "iterations": 2.5, "status": 0, "success": "yes",
    "fallback": None, "speed_reduced": 1,
}


def test_every_field_has_a_bad_value() -> None:
    assert set(BAD_COMMAND) == {f.name for f in dataclasses.fields(Command)}
    assert set(BAD_PLAN) == {f.name for f in dataclasses.fields(Plan)}


def test_a_good_result_passes() -> None:
    command, plan = _good()
    assert check_step_result("mine", 0.5, (command, plan)) == (command, plan)
    # numpy scalars and NaN cost (a failed solve) are fine
    plan = dataclasses.replace(plan, cost=float("nan"), iterations=np.int64(2),
                               success=np.bool_(True))
    check_step_result("mine", 0.5, (dataclasses.replace(command, steer_rad=np.float32(0.1)),
                                    plan))


@pytest.mark.parametrize("field", sorted(BAD_COMMAND))
def test_a_bad_command_field_is_named(field: str) -> None:
    command, plan = _good()
    bad = dataclasses.replace(command, **{field: BAD_COMMAND[field]})
    with pytest.raises(PluginError) as error:
        check_step_result("mine", 0.5, (bad, plan))
    message = str(error.value)
    assert f"step returned Command.{field} = " in message and "expected" in message
    assert "\n" not in message


@pytest.mark.parametrize("field", sorted(BAD_PLAN))
def test_a_bad_plan_field_is_named(field: str) -> None:
    command, plan = _good()
    bad = dataclasses.replace(plan, **{field: BAD_PLAN[field]})
    with pytest.raises(PluginError) as error:
        check_step_result("mine", 0.5, (command, bad))
    message = str(error.value)
    assert f"step returned Plan.{field} = " in message and "expected" in message
    assert "\n" not in message


def test_a_non_finite_command_is_a_failed_step_not_a_broken_interface() -> None:
    command, plan = _good()
    with pytest.raises(TrackerFault, match="non-finite command"):
        check_step_result("mine", 0.5, (dataclasses.replace(command, steer_rad=np.nan), plan))


def test_a_command_beyond_the_bounds_is_clipped_and_said_once(tmp_path: Path) -> None:
    """20 rad of steering from a plug-in ran on without a word (the plant clipped it)."""
    config = load_config("lane-change", tracker="tests.user_trackers:WideSteer",
                         duration_s=1.0, overrides=["tracker.params.fail_at_s=0.5"])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = run(config, tmp_path / "wide.mcap")
    said = [w for w in caught if issubclass(w.category, TrackerCommandClipped)]
    assert len(said) == 1
    assert "steer_rad = 20, beyond +-tracker.max_steer_rad = 0.3927 at t = 0.500 s" in str(
        said[0].message)
    commands = [m["steer_rad"] for _, m in iter_messages(result.log_path, "/control/command")]
    assert max(commands) == pytest.approx(config.tracker.max_steer_rad)


def test_a_path_speed_in_km_per_h_by_mistake_is_said() -> None:
    with pytest.warns(UnitHint, match=r"72 m/s is 259 km/h; if 72 km/h was meant, that is 20"):
        load_config("lane-change", overrides=["path.speed_mps=72"])
    with warnings.catch_warnings():
        warnings.simplefilter("error", UnitHint)
        load_config("lane-change", overrides=["path.speed_mps=40"])
