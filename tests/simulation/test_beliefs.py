"""The plant beside the belief (:mod:`cosim.simulation.beliefs`): no belief follows the plant
unless asked, the request is recorded, and every log carries the mismatch table."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from mcap.reader import make_reader

from cosim.core.config_fields import to_dict
from cosim.core.exceptions import ConfigError
from cosim.simulation.beliefs import belief_pairs, counterpart, mismatch_table
from cosim.simulation.scenario_config import builtin_scenarios, load_config

COSIM = str(Path(sys.executable).with_name("cosim"))


def table(*overrides: str) -> list[tuple[str, object, object]]:
    config = to_dict(load_config("lane-change", overrides=list(overrides)))
    return [(r.quantity, r.plant, r.belief) for r in mismatch_table(config)]


@pytest.mark.parametrize("scenario", sorted(builtin_scenarios()))
def test_every_built_in_scenario_believes_its_plant(scenario: str) -> None:
    """At nominal, the controller's model and the filter's beliefs are the plant's."""
    assert mismatch_table(to_dict(load_config(scenario))) == []


def test_a_plant_key_alone_is_a_mismatch_with_the_resolved_values() -> None:
    assert table("plant.mass_kg=2000") == [("mass_kg", 2000.0, 1575.0)]
    assert table("plant.actuator_delay_s=0.1") == [("actuator_delay_s", 0.1, 0.0)]
    assert table("sensors.gnss.sigma_m=0.3") == [("gnss_sigma_m", 0.3, 0.02)]
    (row,) = mismatch_table(to_dict(load_config("lane-change",
                                                overrides=["plant.mass_kg=2000"])))
    assert row.ratio == pytest.approx(2000.0 / 1575.0)


@pytest.mark.parametrize("belief", ["tracker.latency_s", "tracker.model.mass_kg",
                                    "tracker.model.tyre_friction"])
def test_plant_as_a_belief_tells_the_controller_and_is_recorded(belief: str) -> None:
    plant_key = counterpart(belief)
    assert plant_key is not None
    value = {"tracker.latency_s": 0.1, "tracker.model.mass_kg": 2000,
             "tracker.model.tyre_friction": 0.6}[belief]
    config = load_config("lane-change", overrides=[f"{plant_key}={value}", f"{belief}=plant"])
    assert mismatch_table(to_dict(config)) == []
    assert config.beliefs_from_plant == {belief: plant_key}


def test_a_shown_configuration_loads_back_with_its_request(tmp_path: Path) -> None:
    """``config show`` output as a scenario: the record asks again, so a later change of
    the plant's value in that file is followed by the belief."""
    shown = to_dict(load_config("lane-change", overrides=["plant.actuator_delay_s=0.1",
                                                          "tracker.latency_s=plant"]))
    shown["plant"]["actuator_delay_s"] = 0.2
    path = tmp_path / "mine.yaml"
    path.write_text(yaml.safe_dump(shown))
    again = load_config(str(path))
    assert again.tracker.latency_s == 0.2
    assert again.beliefs_from_plant == {"tracker.latency_s": "plant.actuator_delay_s"}


@pytest.mark.parametrize(("override", "fragment"), [
    ("plant.mass_kg=plant", "plant.mass_kg = 'plant': the plant is the truth"),
    ("beliefs_from_plant=3", "beliefs_from_plant = 3: expected a mapping"),
])
def test_plant_where_it_means_nothing_is_refused(override: str, fragment: str) -> None:
    with pytest.raises(ConfigError, match=fragment):
        load_config("lane-change", overrides=[override])


def test_every_pair_has_both_keys_in_the_configuration() -> None:
    from cosim.simulation.changes import flat_config

    keys = flat_config(to_dict(load_config("lane-change")))
    for pair in belief_pairs():
        assert pair.plant_key in keys and pair.belief_key in keys, pair


def _inspect(log: Path) -> dict:
    done = subprocess.run([COSIM, "inspect", str(log), "--json"], capture_output=True,
                          text=True, timeout=300, check=True)
    return json.loads(done.stdout)


@pytest.mark.slow
def test_the_log_carries_the_mismatch_table(tmp_path: Path) -> None:
    """A heavy car: ``inspect --json`` lists it, and the log's own metadata (read with the
    mcap library) holds the same table; two runs that differ only in what the tracker is
    told about the delay have different tables and different changes."""
    logs = {}
    for name, overrides in (("heavy", ["plant.mass_kg=2000"]),
                            ("delay-unknown", ["plant.actuator_delay_s=0.1"]),
                            ("delay-told", ["plant.actuator_delay_s=0.1",
                                            "tracker.latency_s=0.1"])):
        logs[name] = tmp_path / f"{name}.mcap"
        args = [COSIM, "run", "lane-change", "--duration", "0.5", "--out", str(logs[name])]
        for override in overrides:
            args += ["--set", override]
        subprocess.run(args, capture_output=True, text=True, timeout=300, check=True)
    heavy = _inspect(logs["heavy"])
    (row,) = heavy["mismatch"]
    assert {k: row[k] for k in ("quantity", "plant", "belief")} == {
        "quantity": "mass_kg", "plant": 2000.0, "belief": 1575.0}
    with logs["heavy"].open("rb") as handle:
        metadata = {m.name: m.metadata for m in make_reader(handle).iter_metadata()}
    assert json.loads(metadata["mismatch"]["table_json"]) == heavy["mismatch"]
    unknown, told = _inspect(logs["delay-unknown"]), _inspect(logs["delay-told"])
    assert [r["quantity"] for r in unknown["mismatch"]] == ["actuator_delay_s"]
    assert told["mismatch"] == []
    assert unknown["changes"] != told["changes"]
