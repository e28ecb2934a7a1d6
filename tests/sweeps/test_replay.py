"""A run's logged sensor stream replayed into a fresh filter (cosim/sweeps/replay.py)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from cosim.simulation.scenario_config import ScenarioConfig, load_config
from cosim.sweeps.ensemble import EnsembleMember, run_member
from cosim.sweeps.replay import replay
from estimation.config import scaled_process_noise

SEED = 210
"""A seed no other test uses."""

LoggedRun = tuple[ScenarioConfig, EnsembleMember, Path]
"""A 3 s lane change's configuration, its ensemble member, and its log."""


@pytest.fixture(scope="module")
def logged_run(tmp_path_factory: pytest.TempPathFactory
               ) -> LoggedRun:
    config = load_config("lane-change", overrides=["sensors.suite=gnss"], duration_s=3.0,
                         estimator="ekf")
    out = tmp_path_factory.mktemp("replay")
    member = run_member(config, SEED, out, keep_log=True)
    return config, member, out / f"{config.name}-ekf-{SEED}.mcap"


def test_replay_with_the_runs_own_filter_repeats_it(logged_run: LoggedRun) -> None:
    """Same configuration and seed: the NEES at every log instant and every sensor's NIS
    sums (all, settled, gated at start-up) are the run's own, to rounding."""
    config, member, path = logged_run
    replayed = replay(dataclasses.replace(config, seed=SEED), path)
    np.testing.assert_allclose(replayed.t_s, member.t_s, rtol=0.0, atol=1e-9)
    np.testing.assert_allclose(replayed.nees, member.nees, rtol=1e-9, atol=1e-12)
    assert replayed.nis_dof == member.nis_dof
    assert replayed.nis_sum == pytest.approx(member.nis_sum, rel=1e-9)
    assert replayed.nis_settled_dof == member.nis_settled_dof
    assert replayed.gated_first_s == member.gated_first_s
    assert set(member.nis_dof) == {"gnss", "imu", "steering", "wheel_speed"}
    # Each NEES state's error over its own variance, from the log (the run) and from the
    # replay's estimates: the same figures.
    assert set(replayed.normalized_errors) == {"x_m", "y_m", "yaw_rad", "vx_mps"}
    for name, values in replayed.normalized_errors.items():
        np.testing.assert_allclose(values, member.normalized_errors[name], rtol=1e-6,
                                   atol=1e-12)


def test_replay_with_other_beliefs_is_another_filter_on_one_truth(logged_run: LoggedRun) -> None:
    """Process noise x3: the same instants and updates, a larger covariance, so a smaller
    NEES on average after the first second."""
    config, member, path = logged_run
    config = dataclasses.replace(config, seed=SEED)
    replayed = replay(config, path, scaled_process_noise(config.estimator, 3.0))
    settled = member.t_s >= 1.0
    assert replayed.nis_dof == member.nis_dof
    assert replayed.nees[settled].mean() < member.nees[settled].mean()


def test_a_replay_through_a_workshop_is_a_replay_built_afresh(logged_run: LoggedRun) -> None:
    """A workshop lends the second replay the first one's filter, restarted from the run's
    own initial draw: the same NEES and NIS, bit for bit."""
    from cosim.simulation.workshop import Workshop

    config, _, path = logged_run
    config = dataclasses.replace(config, seed=SEED)
    workshop = Workshop()
    replay(dataclasses.replace(config, seed=SEED + 1), path, workshop=workshop)
    lent = replay(config, path, workshop=workshop)
    fresh = replay(config, path)
    assert workshop.reuses["estimator"] == 1
    assert np.array_equal(lent.nees, fresh.nees) and lent.nis_sum == fresh.nis_sum
