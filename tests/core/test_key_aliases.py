"""Every old spelling of a configuration key still works, and says so in one line.

One test per alias of :data:`cosim.core.key_aliases.KEY_ALIASES`, through ``--set``, through
a scenario file and through a sweep spec's ``set:``; the same key under both names is
refused.
"""

from __future__ import annotations

import dataclasses
import warnings
from pathlib import Path
from typing import Any

import pytest
import yaml

from cosim.core.config_fields import to_dict
from cosim.core.exceptions import ConfigError
from cosim.core.key_aliases import KEY_ALIASES, DeprecatedKeyWarning
from cosim.simulation.scenario_config import load_config
from cosim.sweeps.spec import load_spec

VALUES: dict[str, Any] = {
    "plant.tire_friction": 0.7,
    "plant.tire_model": "contact",
    "tracker.model.tire_friction": 0.8,
    "tracker.ltv_mpc.linearize_about": "reference",
    "tracker.dynamic_mpc.max_steer_rad": 0.2,
    "maneuver": None,  # a section: its keys move with it (maneuver.speed_mps below)
}
"""A value each old key takes that differs from the default of its new key."""


def _case(old: str) -> tuple[str, str, Any]:
    """``(old key, new key, value)``; a section alias is tested through one of its keys."""
    new = KEY_ALIASES[old]
    if VALUES[old] is None:
        return f"{old}.speed_mps", f"{new}.speed_mps", 12.5
    return old, new, VALUES[old]


def _value(config: Any, dotted: str) -> Any:
    node = to_dict(config)
    for part in dotted.split("."):
        node = node[part]
    return node


def _notes(record: list[warnings.WarningMessage]) -> list[str]:
    return [str(w.message) for w in record if issubclass(w.category, DeprecatedKeyWarning)]


def test_every_alias_has_a_case() -> None:
    assert set(VALUES) == set(KEY_ALIASES)


@pytest.mark.parametrize("old", sorted(KEY_ALIASES))
def test_an_old_key_on_the_command_line_works_with_one_note(old: str) -> None:
    old_key, new_key, value = _case(old)
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        via_old = load_config("lane-change", overrides=[f"{old_key}={value}"])
    notes = _notes(record)
    assert notes == [f"{old_key} (--set) is an old spelling: it still works, but write "
                     f"{new_key}"]
    assert "\n" not in notes[0]
    via_new = load_config("lane-change", overrides=[f"{new_key}={value}"])
    assert _value(via_old, new_key) == value
    assert via_old == via_new


@pytest.mark.parametrize("old", sorted(KEY_ALIASES))
def test_an_old_key_in_a_scenario_file_works_with_one_note(old: str, tmp_path: Path) -> None:
    old_key, new_key, value = _case(old)
    data = yaml.safe_load((Path(__file__).parents[2] / "cosim" / "scenarios"
                           / "lane-change.yaml").read_text())
    node = data
    *path, leaf = old_key.split(".")
    for part in path:
        node = node.setdefault(part, {})
    node[leaf] = value
    scenario = tmp_path / "old.yaml"
    scenario.write_text(yaml.safe_dump(data))
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        config = load_config(str(scenario))
    assert len(_notes(record)) == 1 and f"write {KEY_ALIASES[old]}" in _notes(record)[0]
    assert _value(config, new_key) == value


@pytest.mark.parametrize("old", sorted(KEY_ALIASES))
def test_the_same_key_under_both_names_is_refused(old: str, tmp_path: Path) -> None:
    old_key, new_key, value = _case(old)
    scenario = tmp_path / "both.yaml"
    tree: dict[str, Any] = {}
    for key in (old_key, new_key):
        node = tree
        *path, leaf = key.split(".")
        for part in path:
            node = node.setdefault(part, {})
        node[leaf] = value
    scenario.write_text(yaml.safe_dump(tree))
    with pytest.raises(ConfigError, match="under its old and its new name"):
        load_config(str(scenario))


def test_an_old_key_in_a_sweep_spec_works(tmp_path: Path) -> None:
    spec = tmp_path / "spec.yaml"
    spec.write_text("scenario: lane-change\nduration_s: 1\nseeds: 1\n"
                    "set: {plant.tire_friction: 0.9}\ngrid: {tracker.model.tire_friction: "
                    "[0.8, 1.0]}\n")
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        loaded = load_spec(spec)
    notes = _notes(record)
    assert [n.split(" ")[0] for n in notes] == ["plant.tire_friction",
                                               "tracker.model.tire_friction"]
    assert loaded.fixed == (("plant.tyre_friction", 0.9),)
    assert [p.path for p in loaded.parameters] == ["tracker.model.tyre_friction"]


def test_the_steering_bound_is_one_key_with_a_default_per_tracker() -> None:
    """``tracker.max_steer_rad`` unset: dynamic-mpc keeps its reference design's 15 deg,
    every other tracker pi/8; set, it is every tracker's bound."""
    assert load_config("lane-change", tracker="dynamic-mpc").tracker.max_steer_rad == \
        pytest.approx(0.2617993877991494, abs=0.0)
    assert load_config("lane-change").tracker.max_steer_rad == pytest.approx(0.39269908169872414,
                                                                            abs=0.0)
    for name in ("dynamic-mpc", "dynamic-nmpc"):
        config = load_config("lane-change", tracker=name, overrides=["tracker.max_steer_rad=0.3"])
        assert config.tracker.max_steer_rad == 0.3
        assert dataclasses.replace(config.tracker).max_steer_rad == 0.3


def test_the_lead_car_key_is_refused_saying_what_to_write(tmp_path: Path) -> None:
    scenario = tmp_path / "lead.yaml"
    scenario.write_text("name: old-acc\nlead_car: {gap_m: 40, initial_speed_mps: 20}\n")
    with pytest.raises(ConfigError, match=r"^lead_car \(scenario .*\): the single lead car is "
                       r"gone; a traffic car does its job: write traffic: \{lead: "):
        load_config(str(scenario))
    with pytest.raises(ConfigError, match="write traffic:"):
        load_config("lane-change", overrides=["lead_car.gap_m=40"])
