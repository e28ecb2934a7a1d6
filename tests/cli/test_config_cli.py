"""`cosim config show` and `cosim config keys`, as a user calls them (the installed script)."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
import typing
from pathlib import Path

import pytest
import yaml

from cosim.log.reader import read_summary
from cosim.simulation.runner import run
from cosim.simulation.scenario_config import ScenarioConfig, load_config
from tracker.config import TrackerWeights

COSIM = str(Path(sys.executable).with_name("cosim"))

OPTIONS = ("--set", "plant.mass_kg=2000", "--set", "sensors.gnss.sigma_m=0.2",
           "--tracker", "ltv-mpc", "--estimator", "ukf", "--seed", "3", "--duration", "0.3")


def cosim(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([COSIM, *args], capture_output=True, text=True, timeout=300,
                          check=False)


def leaf_keys(cls: type, prefix: str = "") -> list[str]:
    """Every leaf key of a config dataclass, walked here independently of the CLI."""
    keys = []
    hints = typing.get_type_hints(cls)
    for field in dataclasses.fields(cls):
        key = f"{prefix}.{field.name}" if prefix else field.name
        hint = hints[field.name]
        if dataclasses.is_dataclass(hint):
            keys += leaf_keys(hint, key)
        elif typing.get_origin(hint) is tuple:
            keys += leaf_keys(typing.get_args(hint)[0], key + "[]")
        elif typing.get_origin(hint) is dict:  # a free-form section: its owner's keys
            keys.append(key + ".*")
        else:
            keys.append(key)
    return keys


def keys_output(*prefix: str) -> dict[str, list[str]]:
    """``cosim config keys`` as key -> the rest of its row (unit, default, accepted ...)."""
    result = cosim("config", "keys", *prefix)
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert lines[0].split()[:3] == ["key", "unit", "default"]
    return {line.split()[0]: line.split()[1:] for line in lines[1:]}


def test_show_prints_a_scenario_that_resolves_to_the_same_config(tmp_path: Path) -> None:
    result = cosim("config", "show", "lane-change", *OPTIONS)
    assert result.returncode == 0, result.stderr
    printed = tmp_path / "resolved.yaml"
    printed.write_text(result.stdout)
    expected = load_config("lane-change", None, ["plant.mass_kg=2000", "sensors.gnss.sigma_m=0.2"],
                           3, 0.3, "ltv-mpc", "ukf")
    assert expected.plant.mass_kg == 2000 and expected.tracker.name == "ltv-mpc"
    assert load_config(str(printed)) == expected
    assert load_config(str(printed)) != load_config("lane-change")


def test_show_all_prints_what_the_run_logs(tmp_path: Path) -> None:
    result = cosim("config", "show", "--all", "lane-change", *OPTIONS)
    config = load_config("lane-change", None, ["plant.mass_kg=2000", "sensors.gnss.sigma_m=0.2"],
                         3, 0.3, "ltv-mpc", "ukf")
    log = run(config, tmp_path / "run.mcap").log_path
    assert yaml.safe_load(result.stdout) == read_summary(log).config


def test_show_rejects_bad_input_in_one_line() -> None:
    result = cosim("config", "show", "lane-change", "--set", "plant.mass_kg=-5")
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1 and "plant.mass_kg = -5" in result.stderr
    assert result.stdout == ""


def test_keys_lists_every_key_with_its_unit() -> None:
    from cosim.plant.traffic import TrafficCarConfig

    rows = keys_output()
    expected = leaf_keys(ScenarioConfig) + leaf_keys(TrafficCarConfig, "traffic.NAME")
    assert len(expected) > 150
    assert sorted(rows) == sorted(expected)
    suffix_units = {"_s": "s", "_m": "m", "_mps": "m/s", "_mps2": "m/s^2", "_rad": "rad",
                    "_radps": "rad/s", "_kg": "kg", "_npr": "N/rad", "_hz": "Hz"}
    checked = 0
    for key, rest in rows.items():
        for suffix, unit in suffix_units.items():
            if key.endswith(suffix):
                assert rest[0] == unit, (key, rest)
                checked += 1
    assert checked > 80
    assert rows["plant.mass_kg"][:2] == ["kg", "1575.0"]
    assert rows["tracker.name"][0] == "-"


def test_keys_prefix_filters() -> None:
    rows = keys_output("tracker.weights")
    assert sorted(rows) == sorted(f"tracker.weights.{f.name}"
                                  for f in dataclasses.fields(TrackerWeights))


def test_keys_unknown_prefix_is_one_line_and_exit_2() -> None:
    result = cosim("config", "keys", "trackr")
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1
    assert "'trackr'" in result.stderr and "tracker" in result.stderr
    assert "Traceback" not in result.stderr


def test_version() -> None:
    from cosim import __version__

    result = cosim("--version")
    assert result.returncode == 0
    assert result.stdout.strip() == f"cosim {__version__}"


def test_keys_of_a_traffic_car_list_its_settings(capsys: pytest.CaptureFixture[str]) -> None:
    from cosim.cli import main

    assert main(["config", "keys", "traffic.lead"]) == 0
    keys = [line.split()[0] for line in capsys.readouterr().out.splitlines()[1:]]
    assert "traffic.lead.gap_m" in keys and "traffic.lead.speed_profile" in keys
    assert all(key.startswith("traffic.lead.") for key in keys)
    assert main(["config", "keys", "traffic"]) == 0
    assert "traffic.NAME.gap_m" in capsys.readouterr().out
