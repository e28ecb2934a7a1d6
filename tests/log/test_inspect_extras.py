"""`cosim inspect`: warnings (solver failures, rejections, truncation) and CSV export."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest
from mcap.writer import Writer

from cosim.cli import main
from cosim.log import reader
from cosim.log.export import csv_name, export_csv, log_warnings
from cosim.log.reader import (
    ChannelSummary,
    LogSummary,
    _scan_summary,
    iter_messages,
    read_summary,
)
from cosim.simulation.metrics import METRIC_KEYS
from cosim.simulation.runner import RunResult, run
from cosim.simulation.scenario_config import load_config


@pytest.fixture(scope="module")
def good_run(tmp_path_factory: pytest.TempPathFactory) -> RunResult:
    config = load_config("lane-change", duration_s=2.0)
    return run(config, tmp_path_factory.mktemp("inspect") / "good.mcap")


@pytest.fixture(scope="module")
def failing_run(tmp_path_factory: pytest.TempPathFactory) -> RunResult:
    """One IPOPT iteration per step: every solve fails and the tracker falls back (IPOPT
    names the failure ``Maximum_Iterations_Exceeded``)."""
    config = load_config("lane-change", overrides=["tracker.solver=ipopt",
                                                   "tracker.max_iterations=1"],
                         duration_s=2.0)
    return run(config, tmp_path_factory.mktemp("inspect") / "failing.mcap")


def _inspect(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    code = main(["inspect", *args])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def _rows(path: Path) -> tuple[list[str], list[list[str]]]:
    with open(path, newline="", encoding="utf-8") as stream:
        header, *rows = list(csv.reader(stream))
    return header, rows


def test_a_clean_run_has_no_solver_warning(good_run: RunResult,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = _inspect(capsys, str(good_run.log_path), "--json")
    assert code == 0
    document = json.loads(out)
    assert set(METRIC_KEYS) <= set(document["metrics"])
    assert isinstance(document["warnings"], list)
    assert not [w for w in document["warnings"] if "solver" in w or "truncated" in w]


def test_solver_failures_are_named_with_their_status(failing_run: RunResult,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = _inspect(capsys, str(failing_run.log_path), "--json")
    assert code == 0
    document = json.loads(out)
    failures = document["metrics"]["solver_failures"]
    assert failures == 40  # every control step of 2 s at 50 ms
    solver = [w for w in document["warnings"] if w.startswith("solver failures")]
    assert len(solver) == 1
    assert f"{failures} of 40 control steps used a fallback" in solver[0]
    assert "Maximum_Iterations_Exceeded" in solver[0]
    code, text, _ = _inspect(capsys, str(failing_run.log_path))
    assert code == 0
    assert "WARNING: solver failures" in text


def test_rejections_and_aborts_become_warnings(good_run: RunResult) -> None:
    summary = read_summary(good_run.log_path)
    summary.metrics = {**(summary.metrics or {}), "completed": False,
                       "abort_reason": "PhysicsDivergenceError: NaN in qpos",
                       "rejected_measurements": 3, "rejected_gate": 2,
                       "rejected_nonfinite": 1, "channels_gated": 4}
    warnings = log_warnings(summary)
    assert "run did not complete (completed: false): PhysicsDivergenceError: NaN in qpos" \
        in warnings
    assert "estimator rejected 3 measurements (gate 2, nonfinite 1)" in warnings
    assert "estimator gate refused 4 single measurement channels" in warnings


def test_csv_export_of_every_topic(good_run: RunResult, tmp_path: Path,
                                   capsys: pytest.CaptureFixture[str]) -> None:
    out_dir = tmp_path / "csv"
    code, out, _ = _inspect(capsys, str(good_run.log_path), "--csv", str(out_dir))
    assert code == 0
    summary = read_summary(good_run.log_path)
    assert sorted(out.split()) == sorted(str(out_dir / csv_name(c.topic))
                                         for c in summary.channels)
    for channel in summary.channels:
        header, rows = _rows(out_dir / csv_name(channel.topic))
        assert header[0] == "log_time_ns"
        assert len(rows) == channel.message_count, channel.topic
        assert all(len(row) == len(header) for row in rows)
    header, rows = _rows(out_dir / "vehicle_truth.csv")
    assert header == ["log_time_ns", "t_s", "x_m", "y_m", "z_m", "roll_rad", "pitch_rad",
                      "yaw_rad", "vx_mps", "vy_mps", "yaw_rate_radps", "ax_mps2", "ay_mps2",
                      "steer_rad", *(f"wheel_speed_radps[{i}]" for i in range(4)),
                      "gyro_bias_radps", "ax_bias_mps2", "ay_bias_mps2"]
    assert rows[1][0] == "10000000" and float(rows[1][1]) == pytest.approx(0.01)
    # The state names appear once, in the header: no state_names column in the rows; the
    # covariance's columns are named by them (upper triangle, the matrix is symmetric).
    header, rows = _rows(out_dir / "vehicle_estimate.csv")
    (estimate,) = [m for _, m in iter_messages(good_run.log_path, "/vehicle/estimate")][:1]
    names = estimate["state_names"]
    assert not any(h.startswith("state_names") for h in header)
    assert not any(name in cell for row in rows[:3] for cell in row for name in names)
    covariance = [h for h in header if h.startswith("covariance[")]
    assert len(covariance) == len(names) * (len(names) + 1) // 2
    n = len(names)
    for row in range(n):
        for col in range(row, n):
            cell = rows[0][header.index(f"covariance[{names[row]}][{names[col]}]")]
            assert float(cell) == estimate["covariance"][row * n + col]
    assert set(names) <= set(header)  # the mean, by name
    header, rows = _rows(out_dir / "control_plan.csv")
    assert {"solve_time_s", "status", "fallback", "predicted_x_m[0]"} <= set(header)
    assert rows[0][header.index("fallback")] == "false"
    header, _ = _rows(out_dir / "tf.csv")
    assert {"translation.x", "rotation.w", "timestamp.sec"} <= set(header)


def test_csv_export_of_one_topic_with_head(good_run: RunResult, tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    out_dir = tmp_path / "one"
    code, out, _ = _inspect(capsys, str(good_run.log_path), "--csv", str(out_dir),
                            "--topic", "/control/command", "--head", "5")
    assert code == 0
    assert out.split() == [str(out_dir / "control_command.csv")]
    assert [p.name for p in out_dir.iterdir()] == ["control_command.csv"]
    header, rows = _rows(out_dir / "control_command.csv")
    assert {"accel_mps2", "steer_rad"} <= set(header) and len(rows) == 5
    code, _, err = _inspect(capsys, str(good_run.log_path), "--csv", str(out_dir),
                            "--topic", "/nope")
    assert code == 2 and "--topic '/nope'" in err


def test_variable_length_arrays_are_skipped(tmp_path: Path) -> None:
    path = tmp_path / "ragged.mcap"
    with open(path, "wb") as stream:
        writer = Writer(stream)
        writer.start()
        schema = writer.register_schema(name="ragged", encoding="jsonschema", data=b"{}")
        channel = writer.register_channel(topic="/ragged", message_encoding="json",
                                          schema_id=schema)
        for n, values in enumerate(([1.0, 2.0], [3.0], [4.0, 5.0, 6.0])):
            message = {"t_s": n * 0.1, "fixed": [n, -n], "ragged": values, "pose": {"x": n}}
            writer.add_message(channel_id=channel, log_time=n * 100_000_000,
                               data=json.dumps(message).encode(), publish_time=0)
        writer.finish()
    export = export_csv(path, tmp_path / "out", ["/ragged"])
    header, rows = _rows(export.files["/ragged"])
    assert header == ["log_time_ns", "t_s", "fixed[0]", "fixed[1]", "pose.x"]
    assert export.skipped == {"/ragged": ["ragged"]}
    assert rows[2] == ["200000000", "0.2", "2", "-2", "2"]


def test_the_summary_section_gives_what_a_full_scan_gives(good_run: RunResult) -> None:
    # A complete log is summarised from its summary section and indexes; scanning every
    # record (the path a truncated log takes) must find exactly the same.
    indexed = read_summary(good_run.log_path)
    scanned = _scan_summary(good_run.log_path)
    assert indexed.truncated is False and scanned.truncated is False

    def channels(summary: LogSummary) -> list[ChannelSummary]:
        return sorted(summary.channels, key=lambda c: c.topic)

    assert channels(indexed) == channels(scanned)
    assert len(channels(indexed)) >= 10 and indexed.message_count > 1000
    assert (indexed.start_ns, indexed.end_ns) == (scanned.start_ns, scanned.end_ns)
    assert indexed.metadata == scanned.metadata and "run" in indexed.metadata
    assert indexed.attachments == scanned.attachments == ["sedan.xml"]
    assert indexed.metrics == scanned.metrics == good_run.metrics | {
        k: None for k, v in good_run.metrics.items() if isinstance(v, float) and v != v}


def test_reading_a_topic_through_the_indexes_gives_what_a_scan_gives(
        good_run: RunResult, monkeypatch: pytest.MonkeyPatch) -> None:
    indexed = list(iter_messages(good_run.log_path, "/control/plan"))
    monkeypatch.setattr(reader, "_indexed_messages", lambda path, topics: None)  # a scan
    scanned = list(iter_messages(good_run.log_path, "/control/plan"))
    assert len(indexed) == 40 and indexed == scanned
    assert [t for t, _ in indexed] == sorted(t for t, _ in indexed)


def test_a_truncated_log_is_inspected_and_exported(good_run: RunResult, tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    content = good_run.log_path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(content[: len(content) // 2])
    code, out, _ = _inspect(capsys, str(cut), "--json")
    assert code == 0
    document = json.loads(out)
    assert document["truncated"] is True and document["metrics"] == {}
    assert any(w.startswith("truncated file") for w in document["warnings"])
    assert any("no /metrics message" in w for w in document["warnings"])
    counts = {c["topic"]: c["count"] for c in document["channels"]}
    code, _, err = _inspect(capsys, str(cut), "--csv", str(tmp_path / "cut"),
                            "--topic", "/vehicle/truth")
    assert code == 0 and "truncated" in err
    _, rows = _rows(tmp_path / "cut" / "vehicle_truth.csv")
    assert 0 < len(rows) == counts["/vehicle/truth"] < 201
