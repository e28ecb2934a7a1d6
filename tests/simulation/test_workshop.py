"""A workshop's reused plant, filter and tracker run bit for bit as newly built ones.

Each sequence runs differing configurations one after another through one
:class:`~cosim.simulation.workshop.Workshop` (so every part is at some point reused after a
run that left it elsewhere: another seed, another initial state, another car) and compares
every simulated metric of every run with the same configuration run afresh. A part whose
reset forgot something (a warm start, a filter count, an actuator state, a solver's memory)
shows as a differing metric.
"""

from __future__ import annotations

import math

import pytest

from cosim.simulation.metrics import WALL_CLOCK_KEYS
from cosim.simulation.runner import run_unlogged
from cosim.simulation.scenario_config import ScenarioConfig, load_config
from cosim.simulation.workshop import Workshop

pytestmark = pytest.mark.slow

DURATION_S = 4.0
"""Long enough for the lane change's first swerve (the tracker and the filter at work)."""


def _config(seed: int, *overrides: str, tracker: str | None = None,
            estimator: str | None = None) -> ScenarioConfig:
    return load_config("lane-change", None, list(overrides), seed, DURATION_S, tracker,
                       estimator)


def _simulated(metrics: dict[str, object]) -> dict[str, object]:
    """Every metric but those that time the wall clock; NaN as a string (NaN != NaN)."""
    return {k: ("nan" if isinstance(v, float) and math.isnan(v) else v)
            for k, v in metrics.items() if k not in WALL_CLOCK_KEYS}


def _same_as_fresh(configs: list[ScenarioConfig], workshop: Workshop) -> None:
    for i, config in enumerate(configs):
        reused = run_unlogged(config, workshop=workshop)
        fresh = run_unlogged(config)
        assert _simulated(reused.metrics) == _simulated(fresh.metrics), f"run {i}"


def test_the_default_run_reuses_every_part_bit_for_bit() -> None:
    workshop = Workshop()
    _same_as_fresh([
        _config(3),
        _config(4),  # everything kept: another seed (sensor noise, initial estimate)
        _config(5, "initial.speed_mps=12.0", "initial.y_m=0.3"),  # another start
        _config(5, "plant.mass_kg=1700"),  # another car: the plant built again
        _config(6, "plant.mass_kg=1700"),
    ], workshop)
    assert workshop.builds == {"plant": 2, "estimator": 1, "tracker": 1}
    assert workshop.reuses == {"plant": 3, "estimator": 4, "tracker": 4}


@pytest.mark.parametrize("tracker", ["kinematic-nmpc", "dynamic-mpc", "ltv-mpc"])
def test_every_mpc_reused_runs_as_newly_built(tracker: str) -> None:
    workshop = Workshop()
    _same_as_fresh([_config(7, tracker=tracker), _config(8, tracker=tracker)], workshop)
    assert workshop.reuses["tracker"] == 1


def test_the_ukf_reused_runs_as_newly_built() -> None:
    workshop = Workshop()
    _same_as_fresh([_config(9, estimator="ukf"), _config(10, estimator="ukf")], workshop)
    assert workshop.reuses["estimator"] == 1


def test_a_baseline_is_reset_and_a_changed_belief_built_again() -> None:
    """The baselines' memory (integrators, the last steering angle) is reset; a filter and
    an MPC with another belief are another filter and another MPC."""
    workshop = Workshop()
    _same_as_fresh([
        _config(11, tracker="stanley"),
        _config(12, tracker="stanley"),
        _config(12, "tracker.model.mass_kg=1650"),
        _config(13, "tracker.model.mass_kg=1650"),
    ], workshop)
    assert workshop.builds["tracker"] == 2  # stanley once, the NMPC of the new belief once
    assert workshop.builds["estimator"] == 2  # the belief changed once
