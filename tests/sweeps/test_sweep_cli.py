"""`cosim sweep` as users call it: bad specs, worker counts, kill and resume, Ray."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from cosim.core.exceptions import CosimError
from cosim.simulation.metrics import WALL_CLOCK_KEYS
from cosim.sweeps.execute import make_backend
from tests.conftest import Called
from tests.sweeps.rows import wait_for_rows

COSIM = str(Path(sys.executable).with_name("cosim"))

TINY_SPEC = """
scenario: lane-change
duration_s: 1
seeds: [0, 1]
grid: {plant.mass_kg: [1400, 1800]}
pass: {cte_max_m: 0.3, completed: true}
"""
"""Four 1 s runs: two masses, two seeds."""

WALL_CLOCK = (*WALL_CLOCK_KEYS, "started_at", "finished_at", "log")
"""Row fields that measure the machine, not the run."""


def cosim(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "disable")}
    return subprocess.run([COSIM, *args], capture_output=True, text=True, cwd=cwd, env=env,
                          timeout=900, check=False)


def comparable_rows(out: Path) -> list[dict]:
    rows = json.loads((out / "results.json").read_text())["rows"]
    return [{k: v for k, v in row.items() if k not in WALL_CLOCK} for row in rows]


@pytest.fixture(scope="module")
def tiny_spec(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("spec") / "tiny.yaml"
    path.write_text(TINY_SPEC)
    return path


@pytest.fixture(scope="module")
def one_worker(tiny_spec: Path) -> Path:
    """The tiny sweep on one worker: the reference the other ways of running it must match."""
    out = tiny_spec.parent / "one-worker"
    result = cosim("sweep", str(tiny_spec), "--out", str(out), "--workers", "1")
    assert result.returncode == 0, result.stderr
    return out


@pytest.mark.parametrize(
    ("spec", "fragment"),
    [
        ("scenario: lane-change\ngrid: {plant.mas_kg: [1200, 1500]}",
         "grid: 'plant.mas_kg': unknown dotted path"),
        ("scenario: lane-change\ngrid: {}", "grid: empty"),
        ("scenario: lane-change\nrandom: {n: 4, plant.tyre_friction: [1.0, 0.5]}",
         "'plant.tyre_friction': [1.0, 0.5]: expected low <= high"),
        ("scenario: lane-change\ngrid: {plant.mass_kg: [1200]}\npass: {cte_mx_m: 0.3}",
         "pass: unknown metric 'cte_mx_m'"),
    ],
)
def test_bad_spec_is_one_line_and_exit_code_2(spec: str, fragment: str, tmp_path: Path,
                                              cosim_in_process: Callable[..., Called]) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(spec)
    result = cosim_in_process("sweep", str(path), "--out", str(tmp_path / "out"),
                              cwd=tmp_path)
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert fragment in lines[0]
    assert "Traceback" not in result.stderr
    assert not (tmp_path / "out").exists()  # refused before any run


def test_resume_without_a_sweep_is_refused(tiny_spec: Path, tmp_path: Path) -> None:
    result = cosim("sweep", str(tiny_spec), "--out", str(tmp_path / "none"), "--resume")
    assert result.returncode == 2
    assert "holds no sweep to resume" in result.stderr


def test_missing_ray_is_one_clear_error(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray -> ImportError
    with pytest.raises(CosimError, match=r"pip install '\.\[ray\]'"):
        make_backend("ray", None, None)


@pytest.mark.slow
def test_one_and_two_workers_give_identical_results(one_worker: Path, tiny_spec: Path) -> None:
    out = tiny_spec.parent / "two-workers"
    result = cosim("sweep", str(tiny_spec), "--out", str(out), "--workers", "2")
    assert result.returncode == 0, result.stderr
    reference = comparable_rows(one_worker)
    assert [row["run_id"] for row in reference] == [0, 1, 2, 3]
    assert all(row["completed"] is True and not row["error"] for row in reference)
    assert comparable_rows(out) == reference
    summary = (out / "summary.md").read_text()
    assert "## Worst cases by `cte_max_m`" in summary


@pytest.mark.slow
def test_resume_after_a_kill_runs_only_the_missing_runs(one_worker: Path, tiny_spec: Path
                                                        ) -> None:
    out = tiny_spec.parent / "killed"
    rows_file = out / "results.jsonl"
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "disable")}
    process = subprocess.Popen([COSIM, "sweep", str(tiny_spec), "--out", str(out),
                                "--workers", "1"], env=env, start_new_session=True,
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        wait_for_rows(process, rows_file)
    finally:
        os.killpg(process.pid, signal.SIGKILL)  # the CLI and its workers, no clean-up
        process.wait()
    before = [json.loads(line) for line in rows_file.read_text().splitlines()]
    assert 1 <= len(before) < 4

    result = cosim("sweep", str(tiny_spec), "--out", str(out), "--resume")
    assert result.returncode == 0, result.stderr
    assert f"(ran {4 - len(before)} now, {len(before)} from before)" in result.stdout
    after = [json.loads(line) for line in rows_file.read_text().splitlines()]
    assert sorted(row["run_id"] for row in after) == [0, 1, 2, 3]  # each exactly once
    assert after[:len(before)] == before  # the finished rows were not redone
    finished = {row["run_id"]: row["finished_at"]
                for row in json.loads((out / "results.json").read_text())["rows"]}
    assert all(finished[row["run_id"]] == row["finished_at"] for row in before)
    assert comparable_rows(out) == comparable_rows(one_worker)


@pytest.mark.slow
def test_ray_backend_gives_the_same_results(one_worker: Path, tiny_spec: Path) -> None:
    pytest.importorskip("ray")
    out = tiny_spec.parent / "ray"
    result = cosim("sweep", str(tiny_spec), "--out", str(out), "--backend", "ray",
                   "--workers", "2")
    assert result.returncode == 0, result.stderr
    assert comparable_rows(out) == comparable_rows(one_worker)


@pytest.mark.slow
def test_a_plugin_that_exits_fails_its_row_and_the_sweep_goes_on(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """In-process (the pool's workers import ``tests``): one point exits, the other passes."""
    from cosim.cli import main

    spec = tmp_path / "exits.yaml"
    spec.write_text("scenario: lane-change\ntracker: tests.user_trackers:Exiting\n"
                    "duration_s: 0.3\nseeds: 1\ngrid: {tracker.params.fail_at_s: [0.1, 1.0]}\n"
                    "pass: {completed: true}\n")
    code = main(["sweep", str(spec), "--out", str(tmp_path / "out"), "--workers", "2"])
    assert code == 3, capsys.readouterr().err  # one run failed: a CI can gate on it
    rows = [json.loads(line) for line in
            (tmp_path / "out" / "results.jsonl").read_text().splitlines()]
    by_fail = {r["params"]["tracker.params.fail_at_s"]: r for r in rows}
    assert set(by_fail) == {0.1, 1.0}
    assert "called sys.exit(0) at t = 0.100 s" in by_fail[0.1]["error"]
    assert by_fail[1.0]["error"] == "" and by_fail[1.0]["metrics"]["completed"] is True


@pytest.mark.slow
def test_a_run_that_kills_its_worker_is_one_failed_row_and_the_rest_finish(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``os._exit`` in a plug-in takes its worker process down (and the pool with it): the
    run is named in its row's error, the runs beside it and after it still finish."""
    from cosim.cli import main

    spec = tmp_path / "dies.yaml"
    spec.write_text("scenario: lane-change\ntracker: tests.user_trackers:HardExit\n"
                    "duration_s: 0.3\nseeds: 1\n"
                    "grid: {tracker.params.fail_at_s: [1.0, 0.1, 1.1, 1.2]}\n"
                    "pass: {completed: true}\n")
    code = main(["sweep", str(spec), "--out", str(tmp_path / "out"), "--workers", "2"])
    assert code == 3, capsys.readouterr().err  # the dead worker's run failed
    rows = sorted((json.loads(line) for line in
                   (tmp_path / "out" / "results.jsonl").read_text().splitlines()),
                  key=lambda r: r["run_id"])
    assert [r["run_id"] for r in rows] == [0, 1, 2, 3]
    assert rows[1]["error"].startswith("WorkerDiedError: its worker process died")
    for row in (rows[0], rows[2], rows[3]):
        assert row["error"] == "" and row["metrics"]["completed"] is True, row


@pytest.mark.slow
def test_the_acc_braking_example_ends_in_a_collision_as_a_result(tmp_path: Path) -> None:
    """The shipped example: a collision is a run that failed its criteria, with its outcome,
    not an error (the sweep exits 3); the plots show the gap and the time to collision."""
    example = Path(__file__).resolve().parents[2] / "examples" / "acc-braking.yaml"
    done = subprocess.run([COSIM, "sweep", str(example), "--out", str(tmp_path / "out"),
                           "--workers", "2"], capture_output=True, text=True, timeout=1200)
    assert done.returncode == 3, done.stderr  # the collision fails its run
    rows = [json.loads(line) for line in
            (tmp_path / "out" / "results.jsonl").read_text().splitlines()]
    by_decel = {r["params"]["traffic.lead.brake_decel_mps2"]: r for r in rows}
    assert by_decel[9.0]["metrics"]["outcome"] == "collision"
    assert by_decel[9.0]["error"] == ""
    assert by_decel[3.0]["metrics"]["outcome"] == "ok"
    for metric in ("gap_min_m", "ttc_min_s"):
        assert (tmp_path / "out" / f"{metric}-vs-traffic.lead.brake_decel_mps2.png").is_file()
