"""Traffic and adaptive cruise control through the real loop: MuJoCo, the EKF, the range
sensor, the ACC around the LQR path tracker, the MCAP log."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from cosim.core.exceptions import ConfigError
from cosim.log.reader import iter_messages, read_summary
from cosim.plots import plot_logs
from cosim.simulation.runner import RunResult, run, run_unlogged
from cosim.simulation.scenario_config import load_config


def run_acc(tmp_path: Path, scenario: str, *overrides: str,
            duration_s: float | None = None, name: str = "run",
            logged: bool = True) -> RunResult:
    """The scenario with the LQR path tracker; ``logged=False``: no log written (the same
    metrics, bit for bit), for a test that reads the metrics alone."""
    config = load_config(scenario, overrides=["tracker.name=lqr", *overrides],
                         duration_s=duration_s)
    if not logged:
        return run_unlogged(config)
    return run(config, tmp_path / f"{name}.mcap")


@pytest.fixture(scope="module")
def cut_in_start(tmp_path_factory: pytest.TempPathFactory) -> RunResult:
    """The first 2 s of the cut-in scenario: following the lead, nobody cuts in yet."""
    return run_acc(tmp_path_factory.mktemp("acc"), "acc-cut-in", duration_s=2.0)


def test_a_traffic_run_logs_cars_radar_and_the_acc(cut_in_start: RunResult) -> None:
    log = cut_in_start.log_path
    topics = {channel.topic for channel in read_summary(log).channels}
    for topic in ("/traffic/cars", "/traffic/gap", "/scene/traffic", "/sensors/radar",
                  "/acc/gains", "/acc/objective", "/acc/mode"):
        assert topic in topics, topic
    cars = [m for _, m in iter_messages(log, "/traffic/cars")]
    assert {car["name"] for car in cars[-1]["cars"]} == {"lead", "cut_in"}
    readings = [m for _, m in iter_messages(log, "/sensors/radar")]
    assert readings and all(r["target"] == "lead" for r in readings)
    # 2 s at 20 Hz: 41 samples, about 5 % dropped (sensors.radar.dropout_probability).
    assert 30 <= len(readings) < 41
    modes = [m for _, m in iter_messages(log, "/acc/mode")]
    assert modes[-1]["mode"] == "gap" and modes[-1]["target"] == "lead"
    metrics = cut_in_start.metrics
    assert metrics["acc_targets"] == "lead" and metrics["safe_gap_ok"] is True
    assert 40.0 < metrics["gap_min_m"] < 46.0  # started at 45.45 m, the desired 41 m


def test_a_run_without_a_log_builds_no_traffic_message(
        cut_in_start: RunResult, monkeypatch: pytest.MonkeyPatch) -> None:
    """The traffic's messages come from the log's observer alone
    (:mod:`cosim.simulation.traffic_log`): the same 2 s without a log build none (each would
    raise here), and give the logged run's metrics."""
    from cosim.core.traffic_records import CarPose, RangeReading
    from cosim.simulation.metric_keys import WALL_CLOCK_KEYS
    from tracker.cruise.law import AccStatus

    def refused(*args: object) -> dict[str, object]:
        raise AssertionError("a traffic message was built in a run without a log")

    for record, builder in ((CarPose, "to_message"), (RangeReading, "to_message"),
                            (AccStatus, "gains_message")):
        monkeypatch.setattr(record, builder, refused)
    unlogged = run_acc(Path("unused"), "acc-cut-in", duration_s=2.0, logged=False)
    assert unlogged.completed
    logged = cut_in_start.metrics
    assert logged["acc_target_changes"] == 0 and math.isfinite(logged["gap_min_m"])
    assert {k: v for k, v in unlogged.metrics.items() if k not in WALL_CLOCK_KEYS} == \
        {k: v for k, v in logged.items() if k not in WALL_CLOCK_KEYS}


def test_one_seed_one_log(cut_in_start: RunResult, tmp_path: Path) -> None:
    again = run_acc(tmp_path, "acc-cut-in", duration_s=2.0)
    for topic in ("/sensors/radar", "/acc/gains", "/traffic/gap"):
        first = [m for _, m in iter_messages(cut_in_start.log_path, topic)]
        second = [m for _, m in iter_messages(again.log_path, topic)]
        assert first == second, topic


@pytest.mark.slow
def test_cosim_plot_draws_the_acc_figure(cut_in_start: RunResult, tmp_path: Path) -> None:
    written = plot_logs([cut_in_start.log_path], tmp_path)
    assert tmp_path / "acc.png" in written
    assert (tmp_path / "acc.png").stat().st_size > 10_000


def test_driving_into_a_stopped_car_ends_the_run_as_a_collision(tmp_path: Path) -> None:
    """Without the ACC the lane tracker holds 20 m/s into a car standing 30 m ahead."""
    result = run_acc(tmp_path, "acc-braking", "tracker.acc.enabled=false",
                     "traffic.lead.speed_mps=0", "traffic.lead.gap_m=30",
                     duration_s=3.0)
    assert not result.completed
    assert result.outcome == "collision" and result.reason == "collision"
    assert result.metrics["completed"] is False
    # Bumpers meet after 30 - 2.15 - 2.4 m at 20 m/s: 1.27 s (the log step is 10 ms).
    assert result.metrics["collision_t_s"] == pytest.approx(1.27, abs=0.03)
    assert result.metrics["gap_min_m"] < 0.25
    events = [m for _, m in iter_messages(result.log_path, "/events")]
    assert [e["kind"] for e in events] == ["collision"] and "lead" in events[0]["detail"]


def test_gain_settling_is_the_range_over_the_last_window() -> None:
    from cosim.simulation.traffic_loop import GainSettling

    settling = GainSettling(window_s=10.0)
    assert settling.drift_pct() == ()
    for k in range(301):  # 0 to 30 s at 0.1 s
        t_s = 0.1 * k
        # k_x creeps up by 1 % of its final value over the last 10 s; k_vrel oscillates by
        # +-2 % about 0.5 with a 4 s period (no net change from 20 to 30 s: still unsettled).
        k_x = 0.0495 + 0.0005 * max(t_s - 20.0, 0.0) / 10.0
        k_vrel = 0.5 + 0.01 * math.sin(2.0 * math.pi * t_s / 4.0)
        settling.add(t_s, (0.4, k_x, k_vrel), 2.0 + (t_s >= 20.0))
        if k == 50:
            assert not settling.full and math.isnan(settling.objective_mean())
    k_v, k_x, k_vrel = settling.drift_pct()
    assert k_v == 0.0
    assert k_x == pytest.approx(100.0 * 0.0005 / 0.05)
    assert k_vrel == pytest.approx(100.0 * 0.02 / 0.5, rel=1e-3)
    assert settling.objective_mean() == 3.0


def test_acc_needs_traffic() -> None:
    with pytest.raises(ConfigError, match="tracker.acc.enabled = true: expected a scenario "
                                          "with traffic"):
        load_config("lane-change", overrides=["tracker.acc.enabled=true"])


def test_a_bad_traffic_value_names_its_key() -> None:
    with pytest.raises(ConfigError, match="traffic.lead.brake_decel_mps2 = -1"):
        load_config("acc-braking", overrides=["traffic.lead.brake_decel_mps2=-1"])


@pytest.mark.slow
def test_cut_in_retargets_without_collision_or_unsafe_gap(tmp_path: Path) -> None:
    result = run_acc(tmp_path, "acc-cut-in")
    metrics = result.metrics
    assert result.completed and result.outcome == "ok"
    assert metrics["acc_targets"] == "lead,cut_in" and metrics["acc_target_changes"] == 1
    assert metrics["safe_gap_ok"] is True and metrics["safe_gap_margin_min_m"] > 0.0
    gaps = [m for _, m in iter_messages(result.log_path, "/traffic/gap")]
    switch = next(m["t_s"] for m in gaps if m["target"] == "cut_in")
    assert 9.0 < switch < 10.5  # its centre crosses into the lane half way, at 9.5 s
    # The gap opens again towards the desired one behind the new target.
    final = gaps[-1]
    assert final["target"] == "cut_in" and final["gap_m"] > gaps[
        next(i for i, m in enumerate(gaps) if m["target"] == "cut_in")]["gap_m"] + 5.0


@pytest.mark.slow
@pytest.mark.parametrize(("decel_mps2", "outcome"), [(3.0, "ok"), (9.0, "collision")])
def test_braking_lead_within_and_beyond_the_acc_authority(tmp_path: Path, decel_mps2: float,
                                                          outcome: str) -> None:
    """The ACC brakes at most 3.5 m/s^2: a lead braking at 3 is followed to a stop with a
    safe gap; one braking at 9 is hit (the documented limit, docs/acc.md)."""
    result = run_acc(tmp_path, "acc-braking", f"traffic.lead.brake_decel_mps2={decel_mps2}",
                     logged=False)
    assert result.outcome == outcome
    if outcome == "ok":
        assert result.metrics["safe_gap_ok"] is True
        assert result.metrics["accel_min_mps2"] >= -3.5
    else:
        assert not result.completed
        assert result.metrics["accel_min_mps2"] == pytest.approx(-3.5)


@pytest.mark.slow
def test_acc_reaches_the_set_speed_then_keeps_the_gap(tmp_path: Path) -> None:
    """The first 60 s of the ``acc`` scenario: from 400 m behind, at 90 km/h."""
    result = run_acc(tmp_path, "acc", duration_s=60.0)
    metrics = result.metrics
    assert result.completed and result.outcome == "ok"
    assert metrics["acc_set_speed_t_s"] < metrics["acc_gap_mode_t_s"]
    gaps = [m for _, m in iter_messages(result.log_path, "/traffic/gap")]
    at_switch = min(gaps, key=lambda m: abs(m["t_s"] - metrics["acc_gap_mode_t_s"]))
    assert at_switch["gap_m"] > 100.0  # gap keeping starts while the gap is large
    assert metrics["safe_gap_ok"] is True
    assert metrics["acc_speed_err_final_mps"] == pytest.approx(0.0, abs=0.5)


ESC_BEFORE_SETTLING = (
    "tracker.acc.esc.log_objective=true", "tracker.acc.esc.normalise_by_mean=false",
    "tracker.acc.esc.step_decay_s=0", "tracker.acc.esc.highpass_radps=0.02",
    "tracker.acc.esc.lowpass_radps=0.02", "tracker.acc.esc.max_gap_error_m=10",
    "tracker.acc.esc.k_v.frequency_radps=0.1", "tracker.acc.esc.k_x.frequency_radps=0.13",
    "tracker.acc.esc.k_x.step=0.002", "tracker.acc.esc.k_vrel.step=0.01",
    "tracker.acc.esc.k_vrel.lowpass_radps=0")
"""The extremum seeking of the ``acc`` scenario before its gains were made to settle: a
constant step on ``log J``, ``K_x`` perturbed faster than the slow gap mode (docs/acc.md)."""

STEADY_K_VREL_RANGE = (0.38, 0.48)
"""Where the steady objective E[J] of ``acc`` is least along ``K_vrel`` (about 0.43, from a
grid of fixed gains, ``bench/acc_objective_map.py``, docs/acc.md), give or take 0.05; the
minimum of E[log J], where seeking on ``log J`` heads, is above it (about 0.51)."""


@pytest.mark.slow
def test_the_esc_gains_settle_on_the_acc_scenario(tmp_path: Path) -> None:
    """The whole ``acc`` scenario: ESC moves ``K_vrel`` from 0.3 to near the steady
    objective's minimum and every gain then stays within the settling tolerance over the last
    window (``esc_gain_drift_pct``, judged as docs/acc.md says)."""
    result = run_acc(tmp_path, "acc", logged=False)
    metrics = result.metrics
    assert result.completed and result.outcome == "ok"
    esc = load_config("acc").tracker.acc.esc
    assert metrics["esc_gain_drift_pct"] <= esc.settle_tolerance_pct
    assert metrics["esc_gains_settled"] is True
    assert STEADY_K_VREL_RANGE[0] < metrics["acc_k_vrel"] < STEADY_K_VREL_RANGE[1]
    assert metrics["safe_gap_ok"] is True


@pytest.mark.slow
def test_the_earlier_esc_tuning_fails_the_settling_judgement(tmp_path: Path) -> None:
    """The same judgement on the tuning it replaced, over 120 s (half the scenario's former
    240 s; its gains drift by about 60 % there, against a 2 % tolerance): the start-up check
    names the rule it breaks, and the gains are still moving at the end."""
    from tracker.cruise.esc import EscTuningWarning

    with pytest.warns(EscTuningWarning, match="rule 'perturbation slower than the plant': "
                                              "k_x omega = 0.13 rad/s"):
        result = run_acc(tmp_path, "acc", *ESC_BEFORE_SETTLING, duration_s=120.0,
                         logged=False)
    metrics = result.metrics
    assert result.completed
    tolerance = load_config("acc").tracker.acc.esc.settle_tolerance_pct
    assert metrics["esc_gain_drift_pct"] > 2.0 * tolerance
    assert metrics["esc_gains_settled"] is False


def test_render_reads_the_traffic_tracks(cut_in_start: RunResult) -> None:
    from cosim.plots.video_scene import read_logged_scene

    scene = read_logged_scene(cut_in_start.log_path)
    assert set(scene.traffic) == {"lead", "cut_in"}
    lead = scene.traffic["lead"]
    assert lead[-1, 0] == pytest.approx(2.0)
    assert lead[-1, 1] == pytest.approx(50.0 + 20.0 * 2.0)  # gap 50 m, 20 m/s for 2 s
    assert 'name="car_lead/"' in scene.mjcf_xml or "car_lead/" in scene.mjcf_xml


def test_the_acc_foxglove_layout_names_logged_fields(cut_in_start: RunResult) -> None:
    import json

    from cosim.log.reader import iter_topics

    layout = json.loads((Path(__file__).resolve().parents[2] / "examples"
                         / "foxglove-acc-layout.json").read_text())
    first: dict[str, dict] = {}
    for topic, _, message in iter_topics(cut_in_start.log_path):
        first.setdefault(topic, message)
    panels = layout["configById"]
    assert "/scene/traffic" in panels["3D!traffic"]["topics"]
    for panel in panels.values():
        for path in panel.get("paths", []):
            topic, _, field = path["value"].partition(".")
            assert topic in first and field in first[topic], path["value"]
    assert panels["RawMessages!radar"]["topicPath"] in first
