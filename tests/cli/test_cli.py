"""The command line as users (and outside tests) call it: the installed `cosim` script."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from cosim.log.reader import read_summary
from cosim.simulation.metrics import METRIC_KEYS
from cosim.simulation.runner import RunResult
from tests.conftest import Called

COSIM = str(Path(sys.executable).with_name("cosim"))


def cosim(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([COSIM, *args], capture_output=True, text=True, cwd=cwd,
                          timeout=600, check=False)


@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        (("run", "lane-change", "--set", "tracker.horizn=3"), "unknown key 'tracker.horizn'"),
        (("run", "lane-change", "--set", "plant.mass_kg=-1"), "plant.mass_kg = -1"),
        (("run", "nowhere"), "scenario 'nowhere'"),
        (("run", "lane-change", "--tracker", "bang-bang"), "tracker.name = 'bang-bang'"),
        (("run", "lane-change", "--estimator", "magic"), "estimator.name = 'magic'"),
        (("run", "lane-change", "--set", "sim.control_period_s=0.033"), "whole multiple"),
        (("run", "lane-change", "--seed", "abc"), "invalid int value: 'abc'"),
        (("run", "lane-change", "--duration", "-1"), "--duration -1.0"),
        (("inspect", "missing.mcap"), "'missing.mcap': no such file"),
        (("frobnicate",), "invalid choice: 'frobnicate'"),
    ],
)
def test_bad_input_is_one_line_and_exit_code_2(args: tuple[str, ...], fragment: str,
                                               tmp_path: Path,
                                               cosim_in_process: Callable[..., Called]) -> None:
    result = cosim_in_process(*args, cwd=tmp_path)
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert fragment in lines[0]
    assert "Traceback" not in result.stderr


def test_the_console_script_refuses_bad_input_in_one_line(tmp_path: Path) -> None:
    """The installed ``cosim`` script itself (the rows above call its ``main`` in process)."""
    result = cosim("run", "lane-change", "--set", "tracker.horizn=3", cwd=tmp_path)
    assert result.returncode == 2, result.stderr
    (line,) = result.stderr.strip().splitlines()
    assert "unknown key 'tracker.horizn'" in line
    assert "Traceback" not in result.stderr


def test_inspect_json_holds_the_metric_contract(short_run: RunResult) -> None:
    result = cosim("inspect", str(short_run.log_path), "--json")
    assert result.returncode == 0, result.stderr
    document = json.loads(result.stdout)
    assert set(METRIC_KEYS) <= set(document["metrics"])
    assert document["metrics"]["completed"] is True
    topics = {c["topic"]: c for c in document["channels"]}
    assert topics["/vehicle/truth"]["count"] == 201
    assert document["config"]["tracker"]["name"] == "dynamic-nmpc"


def test_inspect_text_and_topic_dump(short_run: RunResult) -> None:
    text = cosim("inspect", str(short_run.log_path))
    assert text.returncode == 0
    assert "/vehicle/truth" in text.stdout and "cte_max_m" in text.stdout
    dump = cosim("inspect", str(short_run.log_path), "--topic", "/sensors/gnss", "--head", "3")
    lines = dump.stdout.strip().splitlines()
    assert len(lines) == 3
    assert {"log_time_ns", "x_m", "y_m"} <= set(json.loads(lines[0]))
    assert json.loads(lines[1])["log_time_ns"] == 100_000_000


def test_run_writes_a_log_and_prints_the_metrics(tmp_path: Path) -> None:
    out = tmp_path / "run.mcap"
    result = cosim("run", "lane-change", "--duration", "1", "--seed", "3", "--out", str(out))
    assert result.returncode == 0, result.stderr
    assert out.is_file()
    assert "cte_max_m" in result.stdout and "completed" in result.stdout
    # The headline fits a screen; --all prints every metric.
    assert len(result.stdout.splitlines()) <= 20 and "nis_gnss" not in result.stdout
    assert f"more metrics: --all, or cosim inspect {out}" in result.stdout
    every = cosim("run", "lane-change", "--duration", "1", "--seed", "3", "--out", str(out),
                  "--force", "--all")
    assert "nis_gnss" in every.stdout and "more metrics" not in every.stdout
    default = cosim("run", "lane-change", "--duration", "0.5", cwd=tmp_path)
    assert default.returncode == 0, default.stderr
    logs = list((tmp_path / "logs").glob("lane-change-*.mcap"))
    assert len(logs) == 1


def test_scenarios_lists_the_builtins() -> None:
    result = cosim("scenarios")
    assert result.returncode == 0
    assert "lane-change " in result.stdout and "lane-change-limit" in result.stdout


@pytest.mark.slow
def test_interrupt_finishes_the_log_with_completed_false(tmp_path: Path) -> None:
    out = tmp_path / "interrupted.mcap"
    process = subprocess.Popen([COSIM, "run", "lane-change", "--out", str(out)],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    # Wait (without timing anything) until the loop has flushed a few chunks of data.
    deadline = time.monotonic() + 300
    while (not out.exists() or out.stat().st_size < 600_000) and process.poll() is None:
        if time.monotonic() > deadline:
            process.kill()
            pytest.fail("the run wrote no data")
        time.sleep(0.02)
    process.send_signal(signal.SIGINT)
    _, stderr = process.communicate(timeout=300)
    assert process.returncode == 130, stderr
    assert "interrupted" in stderr and "Traceback" not in stderr
    summary = read_summary(out)
    assert not summary.truncated
    assert summary.metrics is not None
    assert summary.metrics["completed"] is False
    assert summary.metrics["abort_reason"] == "interrupted"
    truth = {c.topic: c.message_count for c in summary.channels}["/vehicle/truth"]
    assert 0 < truth < 1501
    assert summary.metrics["sim_duration_s"] < 15.0


@pytest.mark.slow
def test_a_killed_run_leaves_a_log_that_inspect_reads(tmp_path: Path) -> None:
    out = tmp_path / "killed.mcap"
    process = subprocess.Popen([COSIM, "run", "lane-change", "--out", str(out)],
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 300
    while (not out.exists() or out.stat().st_size < 700_000) and process.poll() is None:
        if time.monotonic() > deadline:
            break
        time.sleep(0.02)
    process.kill()
    process.wait(timeout=60)
    result = cosim("inspect", str(out), "--json")
    assert result.returncode == 0, result.stderr
    document = json.loads(result.stdout)
    assert document["truncated"] is True
    counts = {c["topic"]: c["count"] for c in document["channels"]}
    # At least a few chunks (256 KiB each) of data survived: seconds of the run.
    assert counts["/vehicle/truth"] > 100
    assert counts.get("/metrics", 0) == 0  # a channel is written with its first message
    assert document["metrics"] == {}


def test_the_command_starts_one_blas_thread_unless_told_otherwise(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """``cosim``'s own process (``main()`` reading the command line) sets one OpenBLAS
    thread for itself and the processes it starts, before numpy is imported; a user's own
    setting stands, and a caller that passes ``argv`` (an embedding process) keeps its
    environment."""
    from cosim.cli import main
    from cosim.cli.common import BLAS_THREADS_VARIABLE

    monkeypatch.setattr(sys, "unraisablehook", sys.unraisablehook)  # main() replaces it
    monkeypatch.setattr(sys, "argv", ["cosim", "scenarios"])
    monkeypatch.delenv(BLAS_THREADS_VARIABLE, raising=False)
    assert main(["scenarios"]) == 0
    assert BLAS_THREADS_VARIABLE not in os.environ
    assert main() == 0
    assert os.environ[BLAS_THREADS_VARIABLE] == "1"
    monkeypatch.setenv(BLAS_THREADS_VARIABLE, "4")
    assert main() == 0
    assert os.environ[BLAS_THREADS_VARIABLE] == "4"
