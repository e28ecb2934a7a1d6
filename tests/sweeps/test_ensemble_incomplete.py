"""An ensemble's run that does not reach its end (cosim/sweeps/ensemble.py)."""

from __future__ import annotations

from pathlib import Path

import pytest

from cosim.simulation.scenario_config import load_config
from cosim.sweeps.ensemble import IncompleteRun, run_member


def test_a_run_that_spins_is_an_incomplete_member_naming_its_seed_and_why(
        tmp_path: Path) -> None:
    """On a road of friction 0.2 the lane change spins the car (about 3 s in): the member
    is an :class:`IncompleteRun` with its seed and the run's own reason (a bench counts and
    names it instead of judging a NEES that stops mid-manoeuvre)."""
    config = load_config("lane-change", overrides=["plant.tyre_friction=0.2"],
                         duration_s=6.0, estimator="ekf")
    with pytest.raises(IncompleteRun) as raised:
        run_member(config, 211, tmp_path)
    assert raised.value.seed == 211
    assert "spun" in raised.value.reason
    assert "seed 211" in str(raised.value)
