"""Consistency statistics (estimation/consistency.py) and a small closed-loop Monte Carlo of
both filters judged by them (slow), including filters whose process noise is wrong by 100x.

The ensemble's ANEES band is derived as the full check derives it (Bar-Shalom, Li,
Kirubarajan 2001, section 5.4.2): chi-square with N runs x 4 dof at every time step after
the first second; the pass criteria are the same as the full 20-seed check's (>= 90 % of the
steps inside, every sensor's NIS per dof in [0.7, 1.4]).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from cosim.simulation.scenario_config import ScenarioConfig, load_config
from cosim.sweeps.ensemble import judge, run_member
from estimation.consistency import chi_square_band, ensemble_consistency, nees_band


def test_band_of_one_run_is_the_chi_square_interval() -> None:
    """One run, 4 DoF: the 2.5 % and 97.5 % quantiles of chi-square(4), 0.4844 and 11.143
    (any table, e.g. Bar-Shalom et al. 2001, table 1.5.4-1)."""
    low, high = nees_band(4, 1)
    assert low == pytest.approx(0.4844, abs=1e-4)
    assert high == pytest.approx(11.143, abs=1e-3)


def test_band_narrows_around_the_dof_with_more_runs() -> None:
    """N runs: chi-square(4 N) / N, centred near 4 and narrowing like 1/sqrt(N); for 20 runs
    [2.858, 5.331]."""
    low, high = nees_band(4, 20)
    assert (low, high) == pytest.approx((2.858, 5.331), abs=1e-3)
    widths = [nees_band(4, n)[1] - nees_band(4, n)[0] for n in (5, 20, 80)]
    assert widths[0] / widths[1] == pytest.approx(2.0, rel=0.1)
    assert widths[1] / widths[2] == pytest.approx(2.0, rel=0.05)
    assert chi_square_band(300) == pytest.approx(nees_band(1, 300))
    with pytest.raises(ValueError):
        nees_band(0, 3)
    with pytest.raises(ValueError):
        nees_band(4, 3, probability=1.5)


def _synthetic(scale: float, runs: int = 10, steps: int = 400, seed: int = 3):
    """NEES of a filter whose errors are ``sqrt(scale)`` times what its covariance says."""
    rng = np.random.default_rng(seed)
    t_s = np.arange(steps) * 0.01
    nees = scale * rng.chisquare(4, size=(runs, steps))
    nis = [{"gnss": scale * float(rng.chisquare(2 * 100))} for _ in range(runs)]
    return ensemble_consistency(t_s, nees, nis, [{"gnss": 200}] * runs, settle_s=1.0)


def test_consistent_ensemble_is_inside_at_about_the_probability() -> None:
    """Independent chi-square(4) draws: about 95 % of the steps inside, NIS per dof near 1."""
    result = _synthetic(1.0)
    assert result.t_s.size == 300 and result.runs == 10
    assert 0.9 <= result.fraction_inside <= 0.99
    assert result.nis["gnss"].nis_per_dof == pytest.approx(1.0, abs=0.1)
    assert result.consistent()
    assert "inside" in "\n".join(result.lines())


@pytest.mark.parametrize("scale, side", [(2.0, "above"), (0.5, "below")])
def test_over_and_under_confidence_fail(scale: float, side: str) -> None:
    """Errors twice (half) what the covariance claims: most steps above (below) the band."""
    result = _synthetic(scale)
    assert not result.consistent()
    assert getattr(result, f"fraction_{side}") > 0.5
    assert not 0.7 <= result.nis["gnss"].nis_per_dof <= 1.4


def test_bad_input_is_refused() -> None:
    t_s = np.arange(10) * 0.5
    with pytest.raises(ValueError, match="columns"):
        ensemble_consistency(t_s, np.ones((2, 9)), [{}, {}], [{}, {}])
    with pytest.raises(ValueError, match="runs"):
        ensemble_consistency(t_s, np.ones((2, 10)), [{}], [{}])
    with pytest.raises(ValueError, match="non-finite"):
        ensemble_consistency(t_s, np.full((2, 10), np.nan), [{}, {}], [{}, {}])


# ------------------------------------------------------------------ closed loop (slow)

SEEDS = (200, 201, 202, 203)
"""Four seeds no other test uses."""
DURATION_S = 5.0

PROCESS_PSDS = (
    "position_psd_m2ps", "yaw_psd_rad2ps", "lateral_accel_psd_m2ps3", "yaw_accel_psd_rad2ps3",
    "jerk_psd_m2ps5", "steer_psd_rad2ps", "steer_rate_psd_rad2ps3", "roll_accel_psd_rad2ps3",
    "rolling_radius_scale_psd_1ps", "wheel_track_scale_psd_1ps", "yaw_transient_psd_s3",
    "roll_accel_relative_psd_s",
)
"""Every process-noise PSD of the filters' model (the bias walks are in estimator.noise)."""


def _config(suite: str, estimator: str, q_factor: float = 1.0) -> ScenarioConfig:
    config = load_config("lane-change", overrides=[f"sensors.suite={suite}"],
                         duration_s=DURATION_S, estimator=estimator)
    if q_factor == 1.0:
        return config
    scaled = {name: q_factor * getattr(config.estimator, name) for name in PROCESS_PSDS}
    noise = config.estimator.noise
    walks = {name: q_factor**0.5 * getattr(noise, name)
             for name in ("gyro_bias_walk_radps", "accel_bias_walk_mps2")}
    estimator_config = dataclasses.replace(
        config.estimator,
        **scaled,
        lateral_residual_sigma_mps2=q_factor**0.5 * config.estimator.lateral_residual_sigma_mps2,
        lateral_residual_relative=q_factor**0.5 * config.estimator.lateral_residual_relative,
        noise=dataclasses.replace(noise, **walks),
    )
    return dataclasses.replace(config, estimator=estimator_config)


@pytest.mark.slow
@pytest.mark.parametrize("suite, estimator", [
    ("rtk", "ekf"),
    pytest.param("gnss", "ukf", marks=pytest.mark.xfail(
        strict=True, reason="known (issue 14): ANEES inside the band at 100 % of the steps, but "
        "the steering sensor's NIS per dof is 1.9 over these first 5 s (1.04 over 15 s): the "
        "corrective steering after a 0.5 m initial error is faster than the steering state's "
        "random walk believes. Strict: once it passes, this mark must go.")),
])
def test_closed_loop_ensemble_is_consistent(suite: str, estimator: str,
                                            tmp_path: Path) -> None:
    """Four runs of the lane change's first 5 s from a sampled initial estimate, the real
    plant and runner: ANEES inside its band at >= 90 % of the steps after 1 s, every
    sensor's NIS per dof in [0.7, 1.4] (bench/estimator_consistency.py runs 20 x 15 s)."""
    config = _config(suite, estimator)
    result = judge([run_member(config, seed, tmp_path) for seed in SEEDS])
    print("\n".join(result.lines()))
    assert set(result.nis) == {"gnss", "imu", "wheel_speed", "steering"}
    assert result.consistent()


@pytest.mark.slow
@pytest.mark.parametrize("q_factor, side", [(100.0, "below"), (0.01, "above")])
def test_process_noise_off_by_100_fails_the_check(q_factor: float, side: str,
                                                  tmp_path: Path) -> None:
    """The same check is not so wide that a badly tuned filter passes: every process noise
    x100 (under-confident: ANEES below the band) or /100 (over-confident: above) fails."""
    config = _config("rtk", "ekf", q_factor)
    result = judge([run_member(config, seed, tmp_path) for seed in SEEDS])
    print("\n".join(result.lines()))
    assert not result.consistent()
    assert getattr(result, f"fraction_{side}") > 0.3
