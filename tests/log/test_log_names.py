"""Default log names: the scenario, a short tag of the overrides, the time."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

from cosim.log.names import MAX_TAG_CHARS, default_log_name, override_tag

COSIM = str(Path(sys.executable).with_name("cosim"))
SAFE = re.compile(r"[A-Za-z0-9.+-]*")


def test_the_tag_names_what_was_overridden() -> None:
    assert override_tag() == ""
    assert override_tag(["plant.mass_kg=2000"]) == "mass2000"
    assert override_tag(["plant.tyre_friction=0.3"], tracker="ltv-mpc", seed=3) == (
        "ltv-mpc-tyre-friction0.3-seed3")
    assert override_tag(["tracker.name=dynamic-mpc"]) == "dynamic-mpc"
    # A plug-in's import path and an FMU's file, readable in a file name.
    assert override_tag(tracker="my_tracker:Proportional") == "my-tracker-Proportional"
    assert override_tag(tracker="fmu:logs/fmu/stanley-fmi3.fmu") == "fmu-stanley-fmi3"
    assert default_log_name("lane-change", "mass2000", "20261201-170301") == (
        "lane-change-mass2000-20261201-170301.mcap")
    assert default_log_name("lane-change", "", "20261201-170301") == (
        "lane-change-20261201-170301.mcap")


def test_the_tag_is_deterministic_short_and_safe() -> None:
    long = [f"sensors.gnss.sigma_m=0.{n}" for n in range(1, 9)]
    odd = ["faults=[{kind: dropout, sensor: gnss, start_s: 5, end_s: 8}]",
           "sim.epoch=2030-01-01T00:00:00Z", "name=a b/c"]
    for overrides in (long, odd, ["plant.mass_kg=2000"]):
        tag = override_tag(overrides)
        assert tag == override_tag(list(overrides))
        assert SAFE.fullmatch(tag) and 0 < len(tag) <= MAX_TAG_CHARS, tag
    # Different overrides, different tags, even when cut.
    assert override_tag(long) != override_tag(long[:-1] + ["sensors.gnss.sigma_m=0.99"])
    assert override_tag(odd[:1]) != override_tag(["faults=[]"])


def test_cosim_run_names_its_log_by_the_overrides(tmp_path: Path) -> None:
    result = subprocess.run([COSIM, "run", "lane-change", "--duration", "0.1", "--set",
                             "plant.mass_kg=2000", "--json"], capture_output=True, text=True,
                            cwd=tmp_path, timeout=300, check=False)
    assert result.returncode == 0, result.stderr
    (log,) = (tmp_path / "logs").iterdir()
    assert re.fullmatch(r"lane-change-mass2000-0.1s-\d{8}-\d{6}\.mcap", log.name), log.name
