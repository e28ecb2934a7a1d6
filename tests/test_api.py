"""The Python API (:mod:`cosim.api`): the example of ``docs/api.md`` runs as written, the
API refuses what the command line refuses with the same message, its results match the
command line's, and ``import cosim`` stays light."""

from __future__ import annotations

import json
import math
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

import cosim
from cosim import api
from cosim.cli import main
from cosim.core.exceptions import CosimError
from cosim.simulation.metrics import WALL_CLOCK_KEYS

ROOT = Path(__file__).resolve().parents[1]


def docs_example() -> str:
    """The one ```python block under "A complete example" in docs/api.md."""
    text = (ROOT / "docs" / "api.md").read_text()
    section = text.split("## A complete example", 1)[1]
    (block,) = re.findall(r"```python\n(.*?)```", section, flags=re.DOTALL)
    return block


@pytest.mark.slow
def test_the_docs_example_runs_as_written(tmp_path: Path) -> None:
    script = tmp_path / "example.py"
    script.write_text(docs_example())
    env = {**os.environ, "MUJOCO_GL": "disable"}
    done = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr
    log = tmp_path / "logs" / "api-example.mcap"
    assert log.is_file()
    assert "refused: tracker.horizon = 1" in done.stdout
    (sweep,) = (tmp_path / "logs").glob("friction-sweep-*")
    rows = (sweep / "results.jsonl").read_text().splitlines()
    frictions = sorted(json.loads(row)["params"]["plant.tyre_friction"] for row in rows)
    assert frictions == [0.7, 1.0]
    # What the example printed is what the log holds.
    assert main(["inspect", str(log), "--json"]) == 0
    time.sleep(1.0)  # the second sweep's folder is named by the second
    again = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=env,
                           capture_output=True, text=True, timeout=900)
    assert again.returncode == 0, again.stderr  # the example runs again as written


def test_run_matches_the_command_line(tmp_path: Path,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    config = cosim.load_config("lane-change", seed=2, duration_s=1.0)
    result = cosim.run(config, out=tmp_path / "api.mcap")
    assert main(["run", "lane-change", "--seed", "2", "--duration", "1", "--json",
                 "--out", str(tmp_path / "cli.mcap")]) == 0
    shown = json.loads(capsys.readouterr().out)["metrics"]
    assert result.completed and result.reason == "" and result.outcome == "ok"
    same_run = {k for k in result.metrics if k not in WALL_CLOCK_KEYS}
    assert {"cte_max_m", "nees_mean", "outcome"} <= same_run
    finite = {k: (None if isinstance(v, float) and not math.isfinite(v) else v)
              for k, v in result.metrics.items()}
    assert {k: finite[k] for k in same_run} == {k: shown[k] for k in same_run}


def _cli_error(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    assert main(argv) == 2
    return capsys.readouterr().err.strip().removeprefix("cosim: error: ")


def test_bad_config_gives_the_cli_message(capsys: pytest.CaptureFixture[str]) -> None:
    cases = [
        (dict(overrides=["tracker.horizon=1"]), ["--set", "tracker.horizon=1"]),
        (dict(overrides=["plant.no_such_key=3"]), ["--set", "plant.no_such_key=3"]),
        (dict(tracker="no-such-tracker"), ["--tracker", "no-such-tracker"]),
    ]
    for kwargs, options in cases:
        with pytest.raises(CosimError) as raised:
            cosim.load_config("lane-change", **kwargs)  # type: ignore[arg-type]
        assert str(raised.value) == _cli_error(["config", "show", "lane-change", *options],
                                               capsys)
    with pytest.raises(CosimError, match="scenario 'no-such-scenario': expected"):
        cosim.load_config("no-such-scenario")


def test_run_refuses_an_existing_log_unless_forced(tmp_path: Path) -> None:
    out = tmp_path / "kept.mcap"
    out.write_bytes(b"the user's file")
    config = cosim.load_config("lane-change", duration_s=0.2)
    with pytest.raises(CosimError, match=r"exists; expected a new file name \(or force=True"):
        cosim.run(config, out=out)
    assert out.read_bytes() == b"the user's file"
    with pytest.raises(CosimError, match="is a folder"):
        cosim.run(config, out=tmp_path)
    result = cosim.run(config, out=out, force=True)
    assert result.completed and out.read_bytes() != b"the user's file"


def test_run_takes_a_scenario_file(tmp_path: Path) -> None:
    scenario = tmp_path / "short.yaml"
    scenario.write_text("seed: 4\nsim:\n  duration_s: 0.2\n")
    result = cosim.run(str(scenario), out=tmp_path / "short.mcap")
    assert result.completed
    assert result.metrics["sim_duration_s"] == pytest.approx(0.2)


def test_bad_arguments_are_named() -> None:
    with pytest.raises(CosimError, match=r"duration_s = nan: expected a number of seconds"):
        cosim.load_config("lane-change", duration_s=float("nan"))
    with pytest.raises(CosimError, match="overrides = 'seed=1': expected a list"):
        cosim.load_config("lane-change", overrides="seed=1")
    with pytest.raises(CosimError, match="config = dict: expected a ScenarioConfig"):
        cosim.run({"seed": 1}, out="never.mcap")  # type: ignore[arg-type]


def test_sweep_refuses_bad_input_before_running(tmp_path: Path) -> None:
    with pytest.raises(CosimError, match="no such file"):
        cosim.sweep(tmp_path / "missing.yaml", out=tmp_path / "out")
    spec = tmp_path / "spec.yaml"
    spec.write_text("scenario: lane-change\nseeds: 1\ngrid:\n  plant.mass_kg: [-5]\n")
    with pytest.raises(CosimError, match="plant.mass_kg"):
        cosim.sweep(spec, out=tmp_path / "out", workers=1)
    with pytest.raises(CosimError, match="workers = 0: expected at least 1"):
        cosim.sweep(spec, out=tmp_path / "out", workers=0)
    (tmp_path / "file").write_text("")
    with pytest.raises(CosimError, match="is a file: expected a directory"):
        cosim.sweep(spec, out=tmp_path / "file")
    assert not (tmp_path / "out").exists()


def test_the_package_exposes_the_api_lazily() -> None:
    assert cosim.run is api.run and cosim.sweep is api.sweep
    assert cosim.load_config is api.load_config and cosim.RunResult is api.RunResult
    assert {"run", "sweep", "load_config"} <= set(dir(cosim))
    with pytest.raises(AttributeError, match="no attribute 'no_such_name'"):
        _ = cosim.no_such_name  # type: ignore[attr-defined]
    probe = ("import sys, cosim; heavy = ('cosim.api', 'mujoco', 'casadi', 'matplotlib', "
             "'cosim.simulation.runner'); print(sorted(m for m in heavy if m in sys.modules))")
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                          check=True)
    assert done.stdout.strip() == "[]"


def test_a_default_run_imports_nothing_heavy_for_one_function(tmp_path: Path) -> None:
    # scipy (a fifth of a second of every start), its statistics, the plots and filterpy
    # (scipy.stats through it) have no place in a default run; nor the other trackers'
    # code, the ACC's or the generated circuits' (tracker.registry imports a tracker's
    # module when a run asks for it); nor the sweep's machinery (cosim.api imports it for
    # cosim.sweep).
    others = ("cosim.sweeps.driver", "multiprocessing",
              "tracker.cruise.law", "tracker.cruise.esc", "tracker.mpc.ltv_mpc",
              "tracker.mpc.dynamic_mpc", "tracker.mpc.kinematic_nmpc", "tracker.open_loop",
              "tracker.baselines.lqr", "tracker.baselines.pid", "tracker.baselines.stanley",
              "tracker.baselines.pure_pursuit", "tracker.paths.generated_circuit")
    probe = ("import sys, cosim; cosim.run(cosim.load_config('lane-change', duration_s=0.2), "
             f"{str(tmp_path / 'run.mcap')!r}); heavy = ('scipy', 'matplotlib', 'filterpy'); "
             "print(sorted(m for m in sys.modules if m.split('.')[0] in heavy)); "
             f"print(sorted(m for m in sys.modules if m in {others!r}))")
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                          check=True, env={**os.environ, "MUJOCO_GL": "disable"})
    assert done.stdout.strip().splitlines()[-2:] == ["[]", "[]"]


def ten_line_tracker() -> str:
    """The ```python block under "Your controller in ten lines" in docs/api.md."""
    text = (ROOT / "docs" / "api.md").read_text()
    section = text.split("## Your controller in ten lines", 1)[1].split("\n## ", 1)[0]
    (block,) = re.findall(r"```python\n(.*?)```", section, flags=re.DOTALL)
    return block


@pytest.mark.slow
def test_the_ten_line_tracker_runs_compares_and_sweeps(tmp_path: Path) -> None:
    (tmp_path / "my_tracker.py").write_text(ten_line_tracker())
    code = [line for line in ten_line_tracker().split("class Proportional", 1)[1].splitlines()
            if line.strip() and not line.strip().startswith(('"""', "#"))]
    assert len(code) <= 10, code
    env = {**os.environ, "MUJOCO_GL": "disable",  # "PYTHONPATH=. cosim ...", as docs say
           "PYTHONPATH": os.pathsep.join(p for p in (".", os.environ.get("PYTHONPATH")) if p)}
    cosim_bin = str(Path(sys.executable).with_name("cosim"))

    def cosim_cli(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run([cosim_bin, *args], cwd=tmp_path, env=env, capture_output=True,
                              text=True, timeout=900)

    ran = cosim_cli("run", "lane-change", "--tracker", "my_tracker:Proportional", "--json")
    assert ran.returncode == 0, ran.stderr
    metrics = json.loads(ran.stdout)["metrics"]
    assert metrics["outcome"] == "ok" and metrics["cte_max_m"] < 0.5
    compared = cosim_cli("compare", "--trackers", "my_tracker:Proportional,pid", "--scenarios",
                         "lane-change", "--duration", "3", "--json", "--workers", "1")
    assert compared.returncode == 0, compared.stderr
    assert {r["tracker"] for r in json.loads(compared.stdout)} == {
        "my_tracker:Proportional", "pid"}
    (tmp_path / "spec.yaml").write_text(
        "scenario: lane-change\ntracker: my_tracker:Proportional\nduration_s: 3\nseeds: 1\n"
        "grid:\n  plant.mass_kg: [1400, 1800]\npass:\n  completed: true\n")
    swept = cosim_cli("sweep", "spec.yaml", "--workers", "1", "--out", "sweep")
    assert swept.returncode == 0, swept.stderr
    rows = (tmp_path / "sweep" / "results.jsonl").read_text().splitlines()
    assert [json.loads(r)["metrics"]["completed"] for r in rows] == [True, True]


def test_runs_sharing_a_workshop_reuse_their_parts_and_give_the_same_numbers(
        tmp_path: Path) -> None:
    """A tuning loop's runs through one :class:`cosim.Workshop`: the second run of the
    same car, filter and tracker builds nothing, and its metrics are a fresh run's."""
    workshop = cosim.Workshop()
    results = [cosim.run(cosim.load_config("lane-change", seed=seed, duration_s=1.0),
                         out=tmp_path / f"shared{seed}.mcap", workshop=workshop)
               for seed in (1, 2)]
    assert workshop.builds == {"plant": 1, "estimator": 1, "tracker": 1}
    assert workshop.reuses == {"plant": 1, "estimator": 1, "tracker": 1}
    fresh = cosim.run(cosim.load_config("lane-change", seed=2, duration_s=1.0),
                      out=tmp_path / "fresh.mcap")
    timing = ("wall_time_s", "realtime_factor", "setup_time_s")
    assert {k: v for k, v in results[1].metrics.items()
            if k not in timing and "_ms_" not in k} == {
        k: v for k, v in fresh.metrics.items() if k not in timing and "_ms_" not in k}
    with pytest.raises(cosim.CosimError, match="workshop = dict: expected a cosim.Workshop"):
        cosim.run(cosim.load_config("lane-change", duration_s=0.2),
                  out=tmp_path / "bad.mcap", workshop={})  # type: ignore[arg-type]
