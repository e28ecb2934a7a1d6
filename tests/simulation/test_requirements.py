"""STL requirements (:mod:`cosim.simulation.requirements`): robustness against a hand
computation on a log read with the mcap library, refusals before any run, and no effect on
what is simulated."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

COSIM = str(Path(sys.executable).with_name("cosim"))
ALWAYS = "always (abs(cte_m) <= 0.3)"
WINDOW = "eventually[0,1] (abs(cte_m) >= 0.005)"


def _cosim(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([COSIM, *args], capture_output=True, text=True, timeout=600)


def _errors(log: Path) -> tuple[np.ndarray, np.ndarray]:
    """``t_s`` and ``cte_m`` of ``/control/errors``, read with the mcap library."""
    t, cte = [], []
    with log.open("rb") as handle:
        for _, channel, message in make_reader(handle).iter_messages(
                topics=["/control/errors"]):
            assert channel.topic == "/control/errors"
            record = json.loads(message.data)
            t.append(record["t_s"])
            cte.append(record["cte_m"])
    return np.array(t), np.array(cte)


@pytest.fixture(scope="module")
def required_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    log = tmp_path_factory.mktemp("stl") / "run.mcap"
    done = _cosim("run", "lane-change", "--duration", "3", "--out", str(log), "--json",
                  "--require", ALWAYS, "--require", WINDOW)
    assert done.returncode == 0, done.stderr
    return log, json.loads(done.stdout)["metrics"]


def test_robustness_agrees_with_a_hand_computation(required_run: tuple[Path, dict]) -> None:
    """``always (|cte| <= 0.3)``: 0.3 - max |cte| over the run; ``eventually[0,1]
    (|cte| >= 0.005)``: max over t in [0, 1] s of |cte| - 0.005 (the bound in seconds)."""
    log, metrics = required_run
    t, cte = _errors(log)
    assert len(t) > 250  # 3 s at the log period
    assert metrics["stl_robustness_0"] == pytest.approx(0.3 - np.max(np.abs(cte)), abs=1e-12)
    window = t <= 1.0 + 1e-9
    assert metrics["stl_robustness_1"] == pytest.approx(
        np.max(np.abs(cte[window])) - 0.005, abs=1e-12)
    assert metrics["stl_robustness"] == min(metrics["stl_robustness_0"],
                                            metrics["stl_robustness_1"])


def test_inspect_evaluates_a_formula_on_the_log(required_run: tuple[Path, dict]) -> None:
    log, metrics = required_run
    done = _cosim("inspect", str(log), "--json", "--require", ALWAYS, "--require",
                  "always (abs(cte_m) <= 0.005)")
    assert done.returncode == 3, done.stderr  # the second is violated
    rows = json.loads(done.stdout)["requirements"]
    assert rows[0] == {"formula": ALWAYS, "robustness": metrics["stl_robustness_0"],
                       "satisfied": True}
    assert rows[1]["satisfied"] is False and rows[1]["robustness"] < 0


def test_requirements_do_not_change_the_run(required_run: tuple[Path, dict],
                                            tmp_path: Path) -> None:
    _, with_requirements = required_run
    done = _cosim("run", "lane-change", "--duration", "3", "--out", str(tmp_path / "a.mcap"),
                  "--json")
    plain = json.loads(done.stdout)["metrics"]
    for key in ("cte_max_m", "cte_rms_m", "heading_err_max_rad", "est_pos_rmse_m",
                "nees_mean", "steer_max_rad"):
        assert plain[key] == with_requirements[key], key


@pytest.mark.parametrize(("args", "fragment"), [
    (["--require", "always (abs(cte) <= 0.3)"], "unknown signal 'cte': expected one of t, "),
    (["--require", "always (abs(cte_m) <= "], "not STL (1:"),
    (["--require", "abs(cte_m) <= 0.3"], "no temporal operator"),
    (["--fail-if", "eventually (yaw > 1)"], "unknown signal 'yaw'"),
    (["--set", "requirements=[{formula: 'always (x < 1)'}]"],
     "requirements[0].formula = 'always (x < 1)': unknown signal 'x'"),
])
def test_a_bad_formula_is_refused_before_any_run(args: list[str], fragment: str,
                                                 tmp_path: Path) -> None:
    out = tmp_path / "never.mcap"
    done = _cosim("run", "lane-change", "--out", str(out), *args)
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and fragment in lines[0], done.stderr
    assert "Traceback" not in done.stderr and not out.exists()


def test_fail_if_a_formula_holds(tmp_path: Path) -> None:
    done = _cosim("run", "lane-change", "--duration", "2", "--out", str(tmp_path / "f.mcap"),
                  "--fail-if", "eventually (abs(cte_m) > 0.001)",
                  "--fail-if", "eventually (abs(cte_m) > 5)")
    assert done.returncode == 3
    last = done.stderr.strip().splitlines()[-1]
    assert last.startswith("cosim: --fail-if 'eventually (abs(cte_m) > 0.001)' holds "
                           "(robustness ")


def test_a_sweep_criterion_in_stl_and_a_bad_one(tmp_path: Path) -> None:
    spec = tmp_path / "spec.yaml"
    spec.write_text("scenario: lane-change\nduration_s: 1\nseeds: 1\n"
                    "grid: {plant.mass_kg: [1500, 1600]}\n"
                    "pass: {stl: 'always (abs(cte_m) <= 0.005)'}\n")
    done = _cosim("sweep", str(spec), "--out", str(tmp_path / "out"), "--workers", "1")
    assert done.returncode == 3, done.stderr  # 1 s of lane change leaves |cte| > 5 mm
    rows = json.loads((tmp_path / "out" / "results.json").read_text())["rows"]
    assert all(r["stl_robustness_0"] is not None for r in rows)
    assert all(r["pass"] == (r["stl_robustness_0"] >= 0) for r in rows)
    bad = tmp_path / "bad.yaml"
    bad.write_text("scenario: lane-change\npass: {stl: 'always (abs(ctem) <= 0.3)'}\n")
    done = _cosim("sweep", str(bad), "--out", str(tmp_path / "bad-out"))
    assert done.returncode == 2 and "unknown signal 'ctem'" in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1


def test_the_docs_list_every_signal() -> None:
    from cosim.simulation.requirements import SIGNALS

    text = (Path(__file__).resolve().parents[2] / "docs" / "requirements.md").read_text()
    for name in SIGNALS:
        assert f"| `{name}` |" in text, name
