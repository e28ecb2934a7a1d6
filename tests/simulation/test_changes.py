"""What a run changed from its scenario: found from resolved configurations, shown in plot
titles, ``cosim inspect`` and default log names."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from cosim.core.config_fields import to_dict
from cosim.plots.data import load_run
from cosim.simulation.changes import base_scenario, config_changes, file_changes
from cosim.simulation.runner import run
from cosim.simulation.scenario_config import load_config

COSIM = str(Path(sys.executable).with_name("cosim"))


def changes(*overrides: str, scenario: str = "lane-change") -> list[str]:
    return config_changes(to_dict(load_config(scenario, overrides=list(overrides))))


def test_a_nominal_run_changes_nothing_and_overrides_are_named() -> None:
    assert changes() == []
    assert changes("plant.mass_kg=2000") == ["plant.mass_kg=2000"]
    assert changes("sim.duration_s=5", "plant.mass_kg=2000") == [
        "sim.duration_s=5", "plant.mass_kg=2000"]
    assert changes("tracker.name=ltv-mpc") == ["tracker.name=ltv-mpc"]
    # Each tracker's own steering bound and steering-rate weight follow it (kinematic-nmpc's
    # weight is 3 where dynamic-nmpc's is 0.3); set against its tracker's default, a change.
    assert changes("tracker.name=kinematic-nmpc") == ["tracker.name=kinematic-nmpc"]
    assert changes("tracker.name=kinematic-nmpc", "tracker.weights.steer_rate=0.3") == [
        "tracker.name=kinematic-nmpc", "tracker.weights.steer_rate=0.3"]
    assert changes("tracker.weights.steer_rate=3") == ["tracker.weights.steer_rate=3"]
    # The seed tells runs apart but is not a change of the scenario.
    assert config_changes(to_dict(load_config("lane-change", seed=7))) == []


def test_what_follows_another_change_is_not_listed() -> None:
    # The filter's beliefs and sensor figures a suite brings are the suite's.
    assert changes("sensors.suite=gnss") == ["sensors.suite=gnss"]
    # A belief told the plant's value shows as the request, not as its number, so two
    # runs that differ in what the controller was told never look alike.
    assert changes("plant.actuator_delay_s=0.1") == ["plant.actuator_delay_s=0.1"]
    assert changes("plant.actuator_delay_s=0.1", "tracker.latency_s=plant") == [
        "plant.actuator_delay_s=0.1", "tracker.latency_s=plant"]
    assert changes("plant.actuator_delay_s=0.1", "tracker.latency_s=0.1") == [
        "plant.actuator_delay_s=0.1", "tracker.latency_s=0.1"]
    # The initial speed a generated circuit's profile gives (resolved by the run, logged
    # resolved) was listed as a change the user never made.
    logged = to_dict(load_config("generated-circuit", overrides=["path.seed=7"]))
    logged["initial"]["speed_mps"] = 25.0
    assert config_changes(logged) == ["path.seed=7"]
    # A belief set on purpose against its suite is a change.
    assert "estimator.noise.gnss_sigma_m=0.3" in changes(
        "sensors.suite=gnss", "estimator.noise.gnss_sigma_m=0.3")


def test_a_scenario_file_is_compared_with_the_built_in_it_came_from(tmp_path: Path) -> None:
    data = to_dict(load_config("circle", overrides=["plant.mass_kg=1900"]))
    data["name"] = "my-circle"
    path = tmp_path / "my-circle.yaml"
    path.write_text(yaml.safe_dump(data))
    assert base_scenario(data) == "circle"
    assert file_changes(str(path)) == ["plant.mass_kg=1900"]
    assert file_changes("circle") == []
    config_file = tmp_path / "wet.yaml"
    config_file.write_text("plant:\n  tyre_friction: 0.5\n")
    assert file_changes("circle", str(config_file)) == ["plant.tyre_friction=0.5"]


@pytest.mark.slow
def test_plots_inspect_and_log_names_show_the_changes(tmp_path: Path) -> None:
    heavy = to_dict(load_config("lane-change", overrides=["plant.mass_kg=2000",
                                                          "sim.duration_s=1"]))
    heavy["name"] = "lane-change-1s"
    scenario = tmp_path / "heavy.yaml"
    scenario.write_text(yaml.safe_dump(heavy))
    done = subprocess.run([COSIM, "run", str(scenario)], cwd=tmp_path, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    (log,) = (tmp_path / "logs").glob("*.mcap")
    assert log.name.startswith("lane-change-1s-duration1-mass2000-"), log.name
    inspected = subprocess.run([COSIM, "inspect", str(log)], capture_output=True, text=True,
                               timeout=120)
    assert "changed from lane-change: sim.duration_s=1, plant.mass_kg=2000" in inspected.stdout
    assert load_run(log).changes == ("sim.duration_s=1", "plant.mass_kg=2000")
    nominal = run(load_config("lane-change", duration_s=1.0), tmp_path / "nominal.mcap")
    assert load_run(nominal.log_path).changes == ("sim.duration_s=1",)
    from cosim.plots.style import suptitle

    class Figure:
        text = ""

        def suptitle(self, text: str, fontsize: float) -> None:
            self.text = text

    figure = Figure()
    suptitle(figure, "Top view", [load_run(log)])
    assert "plant.mass_kg=2000" in figure.text
    suptitle(figure, "Top view", [load_run(nominal.log_path)])
    assert "mass" not in figure.text
