"""Shared fixtures: closed-loop runs are expensive, so each is made once per session."""

from __future__ import annotations

from pathlib import Path

import pytest

from cosim.simulation.runner import RunResult, run
from cosim.simulation.scenario_config import load_config


def run_scenario(tmp_dir: Path, name: str, *overrides: str, seed: int = 0,
                 duration_s: float | None = None, estimator: str | None = None) -> RunResult:
    config = load_config(name, overrides=list(overrides), seed=seed, duration_s=duration_s,
                         estimator=estimator)
    return run(config, tmp_dir / f"{name}-{seed}.mcap")


@pytest.fixture(scope="session")
def short_run(tmp_path_factory: pytest.TempPathFactory) -> RunResult:
    """Two seconds of the lane change, seed 0."""
    return run_scenario(tmp_path_factory.mktemp("short"), "lane-change", duration_s=2.0)


@pytest.fixture(scope="session")
def lane_change_run(tmp_path_factory: pytest.TempPathFactory) -> RunResult:
    """The full 15 s lane change with the EKF in the loop (the README's demo)."""
    return run_scenario(tmp_path_factory.mktemp("full"), "lane-change")
