"""Faults a user's machine throws at cosim: a full or closed stdout, a full disk, a bad
MUJOCO_GL, a killed sweep, a full disk under a sweep, an interrupted sweep, damaged rows.

Each shows one line (or nothing, for a reader that left), no traceback, no data lost.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from cosim.cli import main
from cosim.log.reader import read_summary
from cosim.log.recorder import McapRecorder
from cosim.log.safe_file import partial_path
from cosim.sweeps import driver, results

COSIM = str(Path(sys.executable).with_name("cosim"))
ENV = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "disable")}
QUICK_RUN = ("--tracker", "ltv-mpc")


def _one_clean_line(stderr: str, progress: str = "") -> str:
    """The one line of stderr (lines starting with ``progress`` aside)."""
    lines = [line for line in stderr.strip().splitlines()
             if not (progress and line.startswith(progress))]
    assert len(lines) == 1, stderr
    assert "Traceback" not in stderr
    return lines[0]


def test_a_full_stdout_is_one_line_and_exit_1() -> None:
    with open("/dev/full", "w") as full:
        result = subprocess.run([COSIM, "scenarios"], stdout=full, stderr=subprocess.PIPE,
                                text=True, env=ENV, timeout=300, check=False)
    assert result.returncode == 1
    line = _one_clean_line(result.stderr)
    assert "cannot write" in line and "No space left on device" in line


def test_a_closed_pipe_is_quiet() -> None:
    result = subprocess.run(f"'{COSIM}' scenarios | head -c0", shell=True,
                            capture_output=True, text=True, env=ENV, timeout=300, check=False)
    assert result.stderr == ""


def test_an_unusable_mujoco_gl_does_not_stop_a_plain_run(tmp_path: Path) -> None:
    out = tmp_path / "run.mcap"
    result = subprocess.run([COSIM, "run", "lane-change", "--duration", "0.2", *QUICK_RUN,
                             "--out", str(out)], capture_output=True, text=True,
                            env={**ENV, "MUJOCO_GL": "no-such-backend"}, timeout=600,
                            check=False)
    assert result.returncode == 0, result.stderr
    assert read_summary(out).metrics["completed"] is True


@contextlib.contextmanager
def _tiny_tmpfs(where: Path, size: str) -> Iterator[Path]:
    where.mkdir()
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs",
                              str(where)], capture_output=True, check=False)
    if mounted.returncode != 0:
        pytest.skip("mounting a tmpfs needs root (CI runs as root)")
    try:
        yield where
    finally:
        subprocess.run(["umount", "-l", str(where)], check=False)


@pytest.mark.slow
def test_a_full_disk_ends_the_run_with_one_line_and_keeps_the_log(tmp_path: Path) -> None:
    with _tiny_tmpfs(tmp_path / "disk", "400k") as disk:
        out = disk / "run.mcap"
        result = subprocess.run([COSIM, "run", "lane-change", "--duration", "15", *QUICK_RUN,
                                 "--out", str(out)], capture_output=True, text=True,
                                env=ENV, timeout=900, check=False)
        assert result.returncode == 1, result.stderr
        line = _one_clean_line(result.stderr)
        assert "No space left on device" in line
        summary = read_summary(out)  # what reached the disk is readable
        assert summary.truncated
        truth = {c.topic: c.message_count for c in summary.channels}["/vehicle/truth"]
        assert truth > 10


def test_a_log_takes_its_name_only_when_published(tmp_path: Path) -> None:
    out = tmp_path / "log.mcap"
    out.write_bytes(b"old log")
    recorder = McapRecorder(out)
    assert partial_path(out).exists() and out.read_bytes() == b"old log"
    recorder.publish()
    assert not partial_path(out).exists() and out.read_bytes() != b"old log"
    recorder.close()
    assert read_summary(out).truncated is False

    with pytest.raises(RuntimeError), McapRecorder(out) as refused:
        assert refused.path == out
        raise RuntimeError("refused during set-up")
    assert not partial_path(out).exists()
    assert read_summary(out).truncated is False, "the earlier log is untouched"


SPEC = """\
scenario: lane-change
tracker: ltv-mpc
estimator: ekf
duration_s: {duration}
seeds: {seeds}
grid:
  plant.mass_kg: [1500, 1.6e3]
"""


def _children(pid: int) -> list[int]:
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            with contextlib.suppress(OSError):
                stat = (entry / "stat").read_text()
                if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                    found.append(int(entry.name))
    return found


def _descendants(pid: int) -> list[int]:
    """``pid``'s children, theirs, and so on (a forkserver's workers are grandchildren)."""
    found, frontier = [], [pid]
    while frontier:
        children = [child for parent in frontier for child in _children(parent)]
        found += children
        frontier = children
    return found


def _alive(pid: int) -> bool:
    try:
        state = (Path("/proc") / str(pid) / "stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="reads /proc")
@pytest.mark.slow
def test_sweep_workers_die_with_a_killed_parent(tmp_path: Path) -> None:
    spec = tmp_path / "spec.yaml"
    spec.write_text(SPEC.format(duration=15, seeds=2))
    parent = subprocess.Popen([COSIM, "sweep", str(spec), "--workers", "2", "--out",
                               str(tmp_path / "out")], stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL, env=ENV)
    deadline = time.monotonic() + 300
    children: list[int] = []
    # Two workers, the row queue's manager and the resource tracker (and the forkserver
    # the workers and the manager are forked from, where there is one).
    while len(children) < 4 and time.monotonic() < deadline:
        time.sleep(0.5)
        children = _descendants(parent.pid)
    assert len(children) >= 4, "the sweep started no workers"
    parent.kill()
    parent.wait(timeout=60)
    deadline = time.monotonic() + 180  # a worker still importing dies once it has started
    while any(_alive(child) for child in children) and time.monotonic() < deadline:
        time.sleep(0.2)
    survivors = [child for child in children if _alive(child)]
    for child in survivors:
        os.kill(child, signal.SIGKILL)
    assert not survivors, "workers outlived their parent"


@pytest.mark.slow
def test_a_full_disk_under_a_sweep_is_finished_by_resume(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    spec = tmp_path / "spec.yaml"
    spec.write_text(SPEC.format(duration=0.2, seeds=2))
    out = tmp_path / "out"
    real_append = results.append_row
    calls = []

    def disk_full_after_one(handle: object, row: dict) -> None:
        calls.append(row["run_id"])
        if len(calls) > 1:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(out / "results.jsonl"))
        real_append(handle, row)

    monkeypatch.setattr(driver, "append_row", disk_full_after_one)
    assert main(["sweep", str(spec), "--out", str(out), "--workers", "1"]) == 1
    line = _one_clean_line(capsys.readouterr().err, progress="[")
    assert "No space left on device" in line and "--resume" in line
    assert len(results.SweepDir(out).read_rows()) == 1
    monkeypatch.setattr(driver, "append_row", real_append)
    assert main(["sweep", str(spec), "--out", str(out), "--workers", "1", "--resume"]) == 0
    rows = results.SweepDir(out).read_rows()
    assert sorted(rows) == [0, 1, 2, 3]
    summary = (out / "summary.md").read_text()
    assert "## Outcomes" in summary and "ok 4" in summary
    table = json.loads((out / "results.json").read_text())["rows"]
    assert [row["outcome"] for row in table] == ["ok"] * 4
    assert [row["plant.mass_kg"] for row in table] == [1500, 1500, 1600.0, 1600.0]


def test_an_interrupted_sweep_keeps_its_rows_and_skips_the_plots(tmp_path: Path) -> None:
    spec = tmp_path / "spec.yaml"
    spec.write_text(SPEC.format(duration=0.2, seeds=1))
    out = tmp_path / "out"

    def interrupt(row: dict) -> None:
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        driver.run_sweep(spec, out, workers=1, on_row=interrupt)
    assert (out / "summary.md").is_file() and (out / "results.csv").is_file()
    assert len(results.SweepDir(out).read_rows()) >= 1
    assert not list(out.glob("*.png")), "an interrupt must not wait for the plots"


def test_resume_skips_damaged_rows_and_runs_them_again(tmp_path: Path) -> None:
    directory = results.SweepDir(tmp_path)
    good = {"run_id": 0, "metrics": {}, "interrupted": False}
    directory.rows_file.write_bytes(json.dumps(good).encode() + b"\n"
                                    + b'{"run_id": 1, "x": "\xff\xfe broken'  # torn, not UTF-8
                                    + b"\n\x80\x81\n" + b'{"run_id": 2')
    assert sorted(directory.read_rows()) == [0]
    with directory.open_rows() as handle:
        results.append_row(handle, {"run_id": 3, "metrics": {}, "interrupted": False})
    assert sorted(directory.read_rows()) == [0, 3]


def test_sweep_size_guard_lets_yes_through(tmp_path: Path) -> None:
    spec = tmp_path / "spec.yaml"
    spec.write_text("scenario: lane-change\nseeds: 20000\n")
    with pytest.raises(Exception, match="20,000 runs"):
        driver.run_sweep(spec, tmp_path / "out")
    loaded = driver.load_spec(spec)
    assert loaded.n_runs == 20_000
    driver.check_size(loaded, spec, yes=True)  # refused no more


def test_killed_run_cleanup_never_touches_a_users_file(tmp_path: Path) -> None:
    """A refused run (bad fault channel found while building) leaves --force's target."""
    out = tmp_path / "keep.mcap"
    shutil.copyfile(__file__, out)
    before = out.read_bytes()
    config = tmp_path / "bad.yaml"
    config.write_text("faults:\n  - {kind: stuck, sensor: gnss, channel: z_m}\n")
    assert main(["run", "lane-change", "--config", str(config), "--out", str(out),
                 "--force"]) == 2
    assert out.read_bytes() == before
    assert not partial_path(out).exists()
