"""One log name, one run: a second run on the same ``--out`` is refused before it simulates."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from cosim.core.exceptions import ConfigError
from cosim.log.output_claim import OutputTakenError, claim_output, lock_path
from cosim.log.reader import read_summary

COSIM = str(Path(sys.executable).with_name("cosim"))


def test_a_held_name_is_refused_and_released_after(tmp_path: Path) -> None:
    log = tmp_path / "run.mcap"
    with claim_output(log, "--out", False) as held:
        assert held == log and lock_path(log).exists()
        with pytest.raises(OutputTakenError, match="another cosim run is writing it now"):
            with claim_output(log, "--out", True):
                pass
    assert not lock_path(log).exists()
    with claim_output(log, "--out", False):  # free again
        log.write_bytes(b"the first run's log")
    with pytest.raises(ConfigError, match="exists"):  # checked under the lock
        with claim_output(log, "--out", False):
            pass


def test_a_lock_file_left_by_a_killed_run_is_taken_over(tmp_path: Path) -> None:
    log = tmp_path / "run.mcap"
    lock_path(log).write_text("")  # SIGKILL drops the flock but leaves the file
    with claim_output(log, "--out", False):
        pass


@pytest.mark.slow
def test_two_runs_started_together_on_one_out_exactly_one_proceeds(tmp_path: Path) -> None:
    log = tmp_path / "shared.mcap"
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "disable")}
    args = [COSIM, "run", "lane-change", "--duration", "0.5", "--out", str(log)]
    runs = [subprocess.Popen(args, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             text=True) for _ in range(2)]
    results = [(run.wait(timeout=300), run.stderr.read() if run.stderr else "")
               for run in runs]
    for run in runs:
        for stream in (run.stdout, run.stderr):
            if stream is not None:
                stream.close()
    codes = sorted(code for code, _ in results)
    assert codes == [0, 2], results
    (refusal,) = [err for code, err in results if code == 2]
    (line,) = refusal.strip().splitlines()
    assert str(log) in line
    assert "another cosim run is writing it now" in line or "exists" in line
    summary = read_summary(log)  # the log of the run that proceeded, whole
    assert not summary.truncated and summary.metrics["completed"] is True
    assert not list(tmp_path.glob(".*"))  # no lock or partial file left
