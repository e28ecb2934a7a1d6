"""Trackers from outside cosim: the example package installed with pip runs through
``cosim run``, the API, ``cosim sweep`` and ``cosim compare``; a user's tracker that fails
mid-run ends the run with a reason that names it, the log kept."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

import cosim
from cosim.cli import main
from cosim.log.reader import iter_messages, read_summary

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "pure-pursuit-plugin"
BIN = Path(sys.executable).parent


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    """The example package pip-installed (with its entry point) into a directory of its
    own; the environment of a process that sees it (the venv itself stays unchanged)."""
    target = tmp_path_factory.mktemp("site")
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps",
                    "--target", str(target), str(EXAMPLE)],
                   check=True, capture_output=True, text=True, timeout=600)
    return {**os.environ, "PYTHONPATH": str(target), "MUJOCO_GL": "disable"}


def cosim_cli(env: dict[str, str], cwd: Path, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(BIN / "cosim"), *args], env=env, cwd=cwd,
                          capture_output=True, text=True, timeout=900)


@pytest.mark.slow
def test_the_installed_plugin_is_listed_and_runs(installed: dict[str, str],
                                                 tmp_path: Path) -> None:
    listed = cosim_cli(installed, tmp_path, "trackers")
    assert listed.returncode == 0
    assert "my-pursuit" in listed.stdout and "cosim_pursuit:PurePursuit" in listed.stdout
    # The example's README command, as written there, completes ok.
    readme = (EXAMPLE / "README.md").read_text()
    command = next(line.split("#")[0].split() for line in readme.splitlines()
                   if line.strip().removeprefix(".venv/bin/").startswith("cosim run "))
    done = cosim_cli(installed, tmp_path, *command[1:], "--json", "--out", "pp.mcap")
    assert done.returncode == 0, done.stderr
    metrics = json.loads(done.stdout)["metrics"]
    assert metrics["completed"] and metrics["outcome"] == "ok"
    # It steers: it stays within its lane through both lane changes.
    assert 0.0 < metrics["cte_max_m"] < 1.75 and metrics["steer_max_rad"] > 0.01
    config = read_summary(tmp_path / "pp.mcap").config
    assert config["tracker"]["name"] == "my-pursuit"
    assert config["tracker"]["params"] == {"lookahead_time_s": 0.3}
    refused = cosim_cli(installed, tmp_path, "run", "lane-change", "--tracker", "my-pursuit",
                        "--set", "tracker.params.lookahead_time_s=9")
    assert refused.returncode == 2
    assert "tracker.params.lookahead_time_s = 9: expected a number in [0, 5]" in refused.stderr


@pytest.mark.slow
def test_the_plugin_runs_from_the_api(installed: dict[str, str], tmp_path: Path) -> None:
    script = ("import cosim\n"
              "config = cosim.load_config('lane-change', tracker='my-pursuit', duration_s=2)\n"
              "result = cosim.run(config, out='api.mcap')\n"
              "print(result.completed, result.outcome, result.metrics['steer_max_rad'] > 0)\n")
    done = subprocess.run([sys.executable, "-c", script], env=installed, cwd=tmp_path,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["True", "ok", "True"]


@pytest.mark.slow
def test_the_plugin_runs_in_sweep_and_compare(installed: dict[str, str],
                                              tmp_path: Path) -> None:
    (tmp_path / "spec.yaml").write_text(
        "scenario: lane-change\ntracker: my-pursuit\nduration_s: 2\nseeds: 1\n"
        "grid:\n  tracker.params.lookahead_time_s: [0.3, 0.6]\npass:\n  completed: true\n")
    swept = cosim_cli(installed, tmp_path, "sweep", "spec.yaml", "--workers", "1",
                      "--out", "sweep")
    assert swept.returncode == 0, swept.stderr
    rows = [json.loads(line) for line in
            (tmp_path / "sweep" / "results.jsonl").read_text().splitlines()]
    assert sorted(r["params"]["tracker.params.lookahead_time_s"] for r in rows) == [0.3, 0.6]
    assert all(r["metrics"]["completed"] for r in rows), rows
    compared = cosim_cli(installed, tmp_path, "compare", "--trackers", "my-pursuit,pid",
                         "--scenarios", "lane-change", "--duration", "2", "--workers", "1",
                         "--json", "--out", "league")
    assert compared.returncode == 0, compared.stderr
    runs = json.loads(compared.stdout)
    assert sorted(r["tracker"] for r in runs) == ["my-pursuit", "pid"]
    assert all(r["metrics"]["completed"] for r in runs)
    assert "my-pursuit" in (tmp_path / "league" / "league.md").read_text()


@pytest.mark.parametrize(("tracker", "params", "reason"), [
    ("Raising", ["fail_at_s=0.5"],
     "tracker 'tests.user_trackers:Raising' raised ZeroDivisionError at t = 0.500 s: "
     "the user's bug"),
    ("Exiting", ["fail_at_s=0.5"],
     "tracker 'tests.user_trackers:Exiting' called sys.exit(0) at t = 0.500 s"),
    ("NanSteer", ["fail_at_s=0.5"],
     "tracker 'tests.user_trackers:NanSteer' returned a non-finite command at t = 0.500 s"),
    ("Slow", ["fail_at_s=0.5", "sleep_s=0.2"],
     "tracker 'tests.user_trackers:Slow' took"),
])
def test_a_failing_user_tracker_ends_the_run_with_a_reason(
        tracker: str, params: list[str], reason: str, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    overrides = [f"tracker.params.{p}" for p in params] + ["tracker.step_budget_s=0.05"]
    config = cosim.load_config("lane-change", tracker=f"tests.user_trackers:{tracker}",
                               duration_s=2.0, overrides=overrides)
    result = cosim.run(config, out=tmp_path / "api.mcap")
    assert not result.completed and result.outcome == "error"
    assert result.reason.startswith(reason), result.reason
    summary = read_summary(tmp_path / "api.mcap")  # the log is complete up to the abort
    assert not summary.truncated
    assert summary.metrics is not None and summary.metrics["completed"] is False
    assert summary.metrics["abort_reason"] == result.reason
    assert 0.45 < summary.duration_s < 0.6
    code = main(["run", "lane-change", "--tracker", f"tests.user_trackers:{tracker}",
                 "--duration", "2", *[x for o in overrides for x in ("--set", o)],
                 "--out", str(tmp_path / "cli.mcap")])
    err = capsys.readouterr().err
    assert code == 3 and reason in err and "Traceback" not in err


def test_params_without_a_schema_are_passed_as_a_mapping(tmp_path: Path) -> None:
    """A tracker without ``Params`` gets ``tracker.params`` as it is: here a speed gain."""
    results = {}
    for gain in (0.0, 1.0):
        config = cosim.load_config("lane-change", tracker="tests.user_trackers:NoParams",
                                   duration_s=2.0, overrides=[f"tracker.params.gain={gain}"])
        results[gain] = cosim.run(config, out=tmp_path / f"gain{gain}.mcap")
    assert results[0.0].metrics["accel_max_mps2"] == 0.0
    assert results[1.0].metrics["accel_max_mps2"] > 1.0  # 15 -> 20 m/s at gain 1/s


def test_the_example_depends_on_this_cosim_by_its_distribution_name() -> None:
    """The example asks for cosim's own distribution (installed here, so pip fetches
    nothing): a dependency on the name "cosim" would pull another project from the
    public index."""
    import importlib.metadata
    tomllib = pytest.importorskip("tomllib")  # Python 3.11+

    ours = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["name"]
    example = tomllib.loads((EXAMPLE / "pyproject.toml").read_text())["project"]
    assert ours != "cosim"
    assert example["dependencies"] == [ours]
    assert importlib.metadata.distribution(ours).metadata["Name"] == ours


def test_a_raising_tracker_is_reported_at_its_line_with_the_traceback_on_events(
        tmp_path: Path) -> None:
    config = cosim.load_config("lane-change", tracker="tests.user_trackers:Raising",
                               duration_s=1.0, overrides=["tracker.params.fail_at_s=0.5"])
    result = cosim.run(config, out=tmp_path / "raised.mcap")
    source = ROOT / "tests" / "user_trackers.py"
    line = next(n for n, text in enumerate(source.read_text().splitlines(), 1)
                if "raise ZeroDivisionError" in text)
    assert result.reason.endswith(f"({source}:{line}, in step)"), result.reason
    (event,) = [m for _, m in iter_messages(tmp_path / "raised.mcap", "/events")]
    assert event["kind"] == "tracker_fault"
    assert "Traceback (most recent call last)" in event["detail"]
    assert f'"{source}", line {line}, in step' in event["detail"]


def test_a_tracker_may_return_a_command_alone(tmp_path: Path) -> None:
    config = cosim.load_config("lane-change", tracker="tests.user_trackers:CommandOnly",
                               duration_s=1.0)
    result = cosim.run(config, out=tmp_path / "command.mcap")
    assert result.completed and result.outcome == "ok"
    plans = [m for _, m in iter_messages(tmp_path / "command.mcap", "/control/plan")]
    assert len(plans) == 20 and {p["status"] for p in plans} == {"command"}
    assert result.metrics["accel_max_mps2"] > 0.0


def test_a_module_not_on_the_path_says_how_to_add_the_current_folder(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "mine.py").write_text("class Mine:\n    def step(self): ...\n")
    code = main(["run", "lane-change", "--tracker", "mine:Mine", "--out",
                 str(tmp_path / "x.mcap")])
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert "no module 'mine' on Python's import path" in line
    assert "PYTHONPATH=. cosim" in line
