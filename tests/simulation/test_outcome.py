"""How a run ended: outcome events on /events, the ``outcome`` metric, exit codes and
``--fail-if``; open-loop runs print their manoeuvre metrics."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import pytest

from cosim.cli import EXIT_BAD_OUTCOME, main
from cosim.core.records import VehicleState
from cosim.log.reader import iter_messages
from cosim.simulation.outcome import OutcomeConfig, OutcomeMonitor
from cosim.simulation.runner import run
from cosim.simulation.scenario_config import load_config

COSIM = str(Path(sys.executable).with_name("cosim"))


def _state(t_s: float = 1.0, roll_rad: float = 0.0, vx: float = 20.0, vy: float = 0.0
           ) -> VehicleState:
    return VehicleState(t_s, 0.0, 0.0, 0.5, roll_rad, 0.0, 0.0, vx, vy, 0.0, 0.0, 0.0, 0.0,
                        (60.0,) * 4)


def test_monitor_reports_each_kind_once_and_ranks_them() -> None:
    monitor = OutcomeMonitor(OutcomeConfig(), path_length_m=100.0, tracks_path=True)
    assert monitor.observe(_state(), 0.1, 0.05, 10.0, (4000.0,) * 4) == []
    off = monitor.observe(_state(2.0), 1.8, 0.05, 20.0, None)
    assert [e.kind for e in off] == ["off_road"] and off[0].t_s == 2.0
    assert monitor.observe(_state(2.1), 1.9, 0.05, 21.0, None) == []  # once
    assert monitor.outcome("") == "off_road"
    spun = monitor.observe(_state(3.0, vy=10.0), 0.0, 0.0, 30.0, None)  # slip 0.46 rad
    assert [e.kind for e in spun] == ["spun"]
    assert monitor.outcome("") == "spun"  # more severe than off_road
    assert monitor.outcome("interrupted") == "interrupted"


def test_on_a_track_with_widths_off_road_is_beyond_its_edge() -> None:
    """A circuit 10 m wide left of its line and 4 m right: the car 3 m left is on the road
    (half a 3.5 m lane used to say off_road there), 4.5 m right is off it."""
    def edges(s_m: float) -> tuple[float, float]:
        return 10.0, 4.0

    monitor = OutcomeMonitor(OutcomeConfig(), None, tracks_path=True, road_edges=edges)
    assert monitor.observe(_state(1.0), 3.0, 0.05, 10.0, None) == []
    assert monitor.observe(_state(1.5), -3.9, 0.05, 12.0, None) == []
    off = monitor.observe(_state(2.0), -4.5, 0.05, 20.0, None)
    assert [e.kind for e in off] == ["off_road"] and off[0].threshold == 4.0
    assert "track's edge" in off[0].detail


def test_monitor_rollover_by_roll_or_lifted_wheels() -> None:
    by_angle = OutcomeMonitor(OutcomeConfig(), None, tracks_path=False)
    assert [e.kind for e in by_angle.observe(_state(roll_rad=0.7), 5.0, 2.0, 0.0, None)] \
        == ["rolled_over"]  # open loop: no path events, however far off
    lifted = OutcomeMonitor(OutcomeConfig(wheel_lift_s=0.5), None, tracks_path=True)
    loads = (0.0, 8000.0, 0.0, 8000.0)  # both left wheels in the air
    assert lifted.observe(_state(1.0), 0.0, 0.0, 0.0, loads) == []
    assert lifted.observe(_state(1.3), 0.0, 0.0, 0.0, loads) == []
    assert [e.kind for e in lifted.observe(_state(1.5), 0.0, 0.0, 0.0, loads)] \
        == ["rolled_over"]
    assert lifted.outcome("") == "rolled_over"
    ends = OutcomeMonitor(OutcomeConfig(), 100.0, tracks_path=True)
    assert [e.kind for e in ends.observe(_state(), 0.0, 0.0, 99.5, None)] == ["end_of_path"]
    circuit = OutcomeMonitor(OutcomeConfig(), None, tracks_path=True)
    assert circuit.observe(_state(), 0.0, 0.0, 1e6, None) == []


def _events(log: Path) -> list[dict]:
    return [message for _, message in iter_messages(log, "/events")]


@pytest.mark.slow
def test_a_spin_on_ice_exits_3_with_its_event(tmp_path: Path) -> None:
    out = tmp_path / "ice.mcap"
    result = subprocess.run([COSIM, "run", "lane-change", "--duration", "6", "--set",
                             "plant.tyre_friction=0.3", "--out", str(out)],
                            capture_output=True, text=True, timeout=900, check=False)
    assert result.returncode == EXIT_BAD_OUTCOME, result.stderr
    assert "outcome spun" in result.stderr and "Traceback" not in result.stderr
    events = _events(out)
    spins = [e for e in events if e["kind"] == "spun"]
    assert len(spins) == 1 and 1.0 < spins[0]["t_s"] < 6.0
    assert spins[0]["value"] > spins[0]["threshold"]


@pytest.mark.slow
def test_a_high_car_in_a_sharp_step_steer_rolls_over(tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]
                                                     ) -> None:
    out = tmp_path / "roll.mcap"
    code = main(["run", "step-steer", "--duration", "3", "--set", "plant.cog_height_m=1.6",
                 "--set", "manoeuvre.steer_rad=0.25", "--set", "plant.tyre_friction=1.5",
                 "--out", str(out)])
    captured = capsys.readouterr()
    assert code == EXIT_BAD_OUTCOME
    assert "outcome rolled_over" in captured.err
    assert "cte_max_m" not in captured.out, "an open-loop run follows no path"
    assert "steady_yaw_rate_radps" in captured.out
    kinds = [e["kind"] for e in _events(out)]
    assert kinds[0] == "rolled_over"


def test_starting_off_the_lane_is_off_road(tmp_path: Path) -> None:
    config = load_config("lane-change", duration_s=0.5, tracker="ltv-mpc",
                         overrides=["initial.y_m=2.5"])  # the path starts at y = 0
    result = run(config, tmp_path / "off.mcap")
    # The run stops at the event, so its metrics describe the run up to it.
    assert not result.completed and result.metrics["outcome"] == "off_road"
    assert result.metrics["off_road_t_s"] == 0.0
    assert result.metrics["sim_duration_s"] == 0.0
    assert "stopped at off_road" in result.abort_reason
    assert [e["kind"] for e in _events(tmp_path / "off.mcap")] == ["off_road"]


def test_keep_going_runs_on_after_a_terminal_event(tmp_path: Path) -> None:
    config = load_config("lane-change", duration_s=0.5, tracker="ltv-mpc",
                         overrides=["initial.y_m=2.5", "outcome.keep_going=true"])
    result = run(config, tmp_path / "off.mcap")
    assert result.completed and result.metrics["outcome"] == "off_road"
    assert result.metrics["sim_duration_s"] == pytest.approx(0.5)


def test_driving_past_the_end_of_the_path(tmp_path: Path) -> None:
    config = load_config("lane-change", duration_s=2.0, tracker="ltv-mpc",
                         overrides=["path.kind=straight", "path.length_m=20"])
    result = run(config, tmp_path / "end.mcap")
    assert result.metrics["outcome"] == "end_of_path"
    # 20 m at 15-20 m/s, less the 1 m margin: about a second in.
    assert 0.8 < result.metrics["end_of_path_t_s"] < 1.5


def test_fail_if_turns_a_metric_into_exit_3(tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    base = ["run", "lane-change", "--duration", "0.3", "--tracker", "ltv-mpc"]
    assert main([*base, "--out", str(tmp_path / "a.mcap"), "--fail-if", "cte_max_m>100",
                 "--fail-if", "outcome!=ok"]) == 0
    assert main([*base, "--out", str(tmp_path / "b.mcap"), "--fail-if", "cte_max_m>=0",
                 "--fail-if", "completed==true"]) == EXIT_BAD_OUTCOME
    line = capsys.readouterr().err.strip().splitlines()[-1]
    assert "--fail-if 'cte_max_m>=0' holds (cte_max_m = " in line  # its value, with it
    assert line.endswith(") (and 1 more)")


def test_a_good_run_says_ok(short_run) -> None:  # noqa: ANN001 - conftest fixture
    assert short_run.metrics["outcome"] == "ok"
    assert short_run.metrics["events"] == 0
    assert _events(short_run.log_path) == []
    assert math.isfinite(short_run.metrics["cte_max_m"])


def test_the_run_clock_starts_after_the_set_up(short_run) -> None:  # noqa: ANN001 - fixture
    """The set-up (models, compiled code: a first run's compile took 30 s) is timed apart,
    so that realtime_factor is the simulation's speed, simulated time over wall_time_s."""
    metrics = short_run.metrics
    assert metrics["setup_time_s"] > 0.0 and metrics["wall_time_s"] > 0.0
    assert metrics["realtime_factor"] == pytest.approx(
        metrics["sim_duration_s"] / metrics["wall_time_s"], rel=1e-12)
