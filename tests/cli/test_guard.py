"""``cosim run`` watched from a parent process (:mod:`cosim.cli.guard`): foreign code that
ends the run's process, and interrupts that come while the run is still being set up."""

from __future__ import annotations

import faulthandler
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

from cosim.cli.guard import Death, Reporter, guarded
from cosim.core.compiled_cache import private_folder
from cosim.log.reader import read_summary
from cosim.log.safe_file import partial_path

COSIM = str(Path(sys.executable).with_name("cosim"))
ROOT = Path(__file__).resolve().parents[2]
HARD_EXIT = "tests.user_trackers:HardExit"


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([COSIM, "run", "lane-change", *args], capture_output=True,
                          text=True, errors="surrogateescape", cwd=ROOT, timeout=600)


def test_guarded_returns_the_childs_code_or_how_it_died() -> None:
    assert guarded(lambda reporter: 4) == 4

    def dies(reporter: Reporter) -> int:
        reporter.ready()
        reporter.reached(1.25)
        os._exit(7)

    death = guarded(dies)
    assert death == Death(how="exit status 7", last_t_s=1.25, log_path=None, tracker=None,
                         interrupted=False)

    def crashes(reporter: Reporter) -> int:
        faulthandler.disable()  # pytest's would print the child's stack
        os.kill(os.getpid(), signal.SIGSEGV)
        return 0

    assert guarded(crashes) == Death(how="signal SIGSEGV", last_t_s=None, log_path=None,
                                   tracker=None, interrupted=False)


@pytest.mark.parametrize("ending", ["finishes", "dies"])
def test_the_libraries_a_run_built_for_itself_leave_with_it(
        ending: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """With an unwritable cache a run keeps the libraries it builds in a folder of its own
    (cosim.core.compiled_cache.private_folder), which its exit handlers remove; the run's
    process ends with os._exit or a signal, so the guard removes it (before: left behind
    in the temporary directory by every such run)."""
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))  # tempfile.gettempdir()'s

    def builds(reporter: Reporter) -> int:
        folder = private_folder() / "0123456789abcdef"
        folder.mkdir(parents=True)
        (folder / "library.so").write_bytes(b"built")
        if ending == "dies":
            os.kill(os.getpid(), signal.SIGKILL)
        return 0

    guarded(builds)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("fail_at_s", [2.5, 0.3])
def test_a_plugin_that_ends_the_process_is_named_and_the_log_kept(
        fail_at_s: float, tmp_path: Path) -> None:
    """Before the guard: exit 7, nothing printed, and at 0.3 s no readable log. The parent
    writes the log (cosim.log.piped_recorder) and finishes it with what the run had sent:
    before that, the child's log ended at its last complete chunk (at 2.5 s, t = 2.0 s;
    at 0.3 s, the header alone)."""
    out = tmp_path / "hard-exit.mcap"
    done = _run("--tracker", HARD_EXIT, "--set", f"tracker.params.fail_at_s={fail_at_s}",
                "--out", str(out), "--json")
    assert done.returncode == 3, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in done.stderr, done.stderr
    assert "the run's process died" in lines[0] and "exit status 7" in lines[0]
    assert f"the tracker {HARD_EXIT!r} is a plug-in" in lines[0]
    assert str(out) in lines[0]
    document = json.loads(done.stdout)
    assert document["metrics"]["completed"] is False
    assert document["metrics"]["outcome"] == "error"
    summary = read_summary(out)  # finished, summary included, the config with it
    assert not summary.truncated and fail_at_s - 0.2 <= summary.duration_s <= fail_at_s
    assert "config_json" in summary.metadata["run"]
    assert {c.topic for c in summary.channels} >= {"/vehicle/truth", "/control/command"}
    assert "every message the run sent" in lines[0]
    assert not partial_path(out).exists()


def _started(out: Path, process: subprocess.Popen[str]) -> None:
    """Wait (without timing anything) until the child has begun its set-up: the log's
    temporary file exists."""
    deadline = time.monotonic() + 300
    while not partial_path(out).exists() and not out.exists() and process.poll() is None:
        if time.monotonic() > deadline:
            process.kill()
            pytest.fail("the run never started its log")
        time.sleep(0.005)


@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_an_interrupt_during_set_up_stops_the_run_at_its_start(signum: int,
                                                               tmp_path: Path) -> None:
    """Before the guard a SIGTERM during set-up exited 143 without a word, and a Ctrl-C
    that native code swallowed let the run go on to exit 0."""
    out = tmp_path / "early.mcap"
    process = subprocess.Popen([COSIM, "run", "lane-change", "--out", str(out)],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               cwd=ROOT, start_new_session=True)
    _started(out, process)
    os.killpg(process.pid, signum)  # as a terminal's Ctrl-C reaches every process
    _, stderr = process.communicate(timeout=300)
    assert process.returncode == 130, stderr
    assert "interrupted" in stderr and "Traceback" not in stderr
    if out.exists():  # stopped at its first step: a complete log saying so
        summary = read_summary(out)
        assert summary.metrics is not None and summary.metrics["completed"] is False
        assert summary.metrics["sim_duration_s"] < 1.0
    assert not partial_path(out).exists()


def test_a_bug_in_the_child_is_shown_not_swallowed(capfd: pytest.CaptureFixture[str]) -> None:
    def buggy(reporter: Reporter) -> int:
        raise ZeroDivisionError("a bug")

    assert guarded(buggy) == 1
    assert "ZeroDivisionError: a bug" in capfd.readouterr().err


def test_a_log_name_that_is_not_utf8_is_run(tmp_path: Path) -> None:
    """Before: exit 1 and nothing said (the child could not tell the parent the name)."""
    out = Path(os.fsdecode(bytes(tmp_path) + b"/log-\xff.mcap"))
    done = _run("--duration", "0.5", "--out", str(out))
    assert done.returncode == 0, done.stderr
    assert read_summary(out).metrics is not None


def test_an_interrupt_just_after_the_log_is_published_finishes_it(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The interrupt in the instant between the log taking its final name and the loop
    taking Ctrl-C over (what the test above hit once in a fresh clone: a published log
    without /metrics): the log is finished, ``completed: false``, the run says why."""
    from cosim.log.recorder import McapRecorder
    from cosim.simulation.runner import run
    from cosim.simulation.scenario_config import load_config

    publish = McapRecorder.publish

    def publish_then_interrupt(self: McapRecorder) -> None:
        publish(self)
        raise KeyboardInterrupt

    monkeypatch.setattr(McapRecorder, "publish", publish_then_interrupt)
    out = tmp_path / "early.mcap"
    result = run(load_config("lane-change", duration_s=1.0), out)
    assert result.abort_reason == "interrupted" and not result.completed
    summary = read_summary(out)
    assert summary.metrics is not None and summary.metrics["completed"] is False
