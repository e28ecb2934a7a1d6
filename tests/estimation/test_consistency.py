"""Consistency statistics (estimation/consistency.py) and closed-loop Monte Carlos of the
filters judged by them (slow), with filters whose process noise is wrong by x0.3 and x3 (and
x0.01, x100) shown to fail.

The ensemble's ANEES band is derived as the full check derives it (Bar-Shalom, Li,
Kirubarajan 2001, section 5.4.2): chi-square with N runs x 4 dof at every time step after
the first second; the pass criteria are the same as the full check's (>= 90 % of the steps
inside, every sensor's NIS per dof after the first second in [0.9, 1.1]). With 20 runs the
band is [2.86, 5.33]; ``Q`` x0.3 moves the mean ANEES from 3.9 to 4.4, still within it (since
the filter's model has the front wheels' moment, 97 % of its steps stay inside), and ``Q`` x3
hardly moves it (the sensors pin the errors down): both show in the IMU's innovations, NIS
per dof 1.15 and 0.88 against the nominal filter's 1.01. Twenty closed-loop runs are logged
once; each mistuned filter is the run's filter replayed over the same sensor stream with its
process noise scaled (:mod:`cosim.sweeps.replay`), so the whole sweep costs twenty runs.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from cosim.simulation.scenario_config import ScenarioConfig, load_config
from cosim.simulation.workshop import Workshop
from cosim.sweeps.ensemble import EnsembleMember, judge, run_member
from cosim.sweeps.replay import LoggedRun, logged_run, replay
from estimation.config import scaled_process_noise
from estimation.consistency import (
    anees_standard_error,
    chi_square_band,
    chi_square_quantile,
    ensemble_consistency,
    false_alarms,
    nees_band,
)


def test_band_of_one_run_is_the_chi_square_interval() -> None:
    """One run, 4 DoF: the 2.5 % and 97.5 % quantiles of chi-square(4), 0.4844 and 11.143
    (any table, e.g. Bar-Shalom et al. 2001, table 1.5.4-1)."""
    low, high = nees_band(4, 1)
    assert low == pytest.approx(0.4844, abs=1e-4)
    assert high == pytest.approx(11.143, abs=1e-3)


@pytest.mark.parametrize("dof", [1, 2, 3, 4, 7, 13, 50, 101, 1000, 4503])
def test_the_quantile_is_scipys_in_both_tails(dof: int) -> None:
    from scipy.special import gammaincinv  # the reference; the runs never import scipy

    for probability in (1e-9, 1e-4, 0.005, 0.025, 0.3, 0.5, 0.7, 0.975, 0.99, 1 - 1e-9):
        expected = 2.0 * float(gammaincinv(dof / 2.0, probability))
        assert chi_square_quantile(probability, dof) == pytest.approx(expected, rel=1e-12)
    with pytest.raises(ValueError, match="dof = 0"):
        chi_square_quantile(0.5, 0)
    with pytest.raises(ValueError, match="probability = 1.0"):
        chi_square_quantile(1.0, dof)


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


def test_worst_window_finds_a_burst_above_the_band() -> None:
    """A consistent ensemble but for one 1 s stretch where the errors are three times what
    the covariance says: the steps above the band are few over the whole run, but the
    window over that stretch is mostly above."""
    rng = np.random.default_rng(4)
    runs, t_s = 20, np.arange(1500) * 0.01
    nees = rng.chisquare(4, size=(runs, t_s.size))
    burst = (t_s >= 6.0) & (t_s < 7.0)
    nees[:, burst] *= 3.0
    result = ensemble_consistency(t_s, nees, [{}] * runs, [{}] * runs)
    assert result.fraction_above < 0.1
    assert result.worst_window_above(1.0) > 0.9
    calm = ensemble_consistency(t_s, rng.chisquare(4, size=(runs, t_s.size)), [{}] * runs,
                                [{}] * runs)
    assert calm.worst_window_above(1.0) < 0.2
    with pytest.raises(ValueError, match="positive"):
        result.worst_window_above(0.0)


def test_window_means_show_where_the_filter_is_over_and_under_confident() -> None:
    """100 runs in one band: a filter whose errors are 1.4 times its belief in one second
    (a swerve) and 0.8 times in another (the straight after it) shows both in the window
    means, while the whole run's mean ANEES stays near 4."""
    rng = np.random.default_rng(5)
    runs, t_s = 100, np.arange(1500) * 0.01
    nees = rng.chisquare(4, size=(runs, t_s.size))
    nees[:, (t_s >= 3.0) & (t_s < 4.0)] *= 1.4
    nees[:, (t_s >= 5.0) & (t_s < 6.0)] *= 0.8
    result = ensemble_consistency(t_s, nees, [{}] * runs, [{}] * runs)
    low, high = result.band
    means = dict(result.window_means(1.0))
    assert sorted(means) == [float(k) for k in range(1, 15)]  # from the first judged step
    assert means[3.0] > high and means[5.0] < low
    assert all(low <= m <= high for start, m in means.items() if start not in (3.0, 5.0))
    assert 3.7 < result.anees_mean < 4.3
    with pytest.raises(ValueError, match="positive"):
        result.window_means(-1.0)


def test_the_mean_anees_moves_with_the_runs_drawn_when_their_steps_are_correlated() -> None:
    """Independent draws at every step: the runs' spread gives the standard error of
    independent steps. Each run's NEES scaled by a factor of its own (a run high or low all
    along, as a sampled initial error makes it): the same mean, a standard error many times
    the independent one, which is what moves a judged fraction from one seed range to the
    next."""
    rng = np.random.default_rng(5)
    t_s = np.arange(600) * 0.01
    independent = rng.chisquare(4, size=(40, t_s.size))
    factors = rng.lognormal(0.0, 0.35, size=(40, 1))
    correlated = independent * factors / factors.mean()
    error, if_independent = anees_standard_error(t_s, independent)
    assert if_independent == pytest.approx(math.sqrt(8.0 / (40 * 500)))
    assert error == pytest.approx(if_independent, rel=0.3)
    error, _ = anees_standard_error(t_s, correlated)
    assert error > 5.0 * if_independent
    with pytest.raises(ValueError, match="two runs"):
        anees_standard_error(t_s, independent[:1])


@pytest.mark.parametrize("tested, gate_probability", [
    (22_000, 0.9999), (100, 0.9999), (0, 0.9999), (5_000, 0.99), (1, 0.5), (300, 0.999)])
def test_a_consistent_filters_gating_is_the_binomial_quantile(
        tested: int, gate_probability: float) -> None:
    """Each tested update is refused with probability 1 - gate_probability: the count's
    mean and its 95 % quantile are the binomial's (scipy's, the reference)."""
    from scipy.stats import binom

    chance = false_alarms(tested, gate_probability)
    assert chance.tested == tested
    assert chance.expected == pytest.approx(tested * (1.0 - gate_probability), rel=1e-9)
    assert chance.at_most == int(binom.ppf(0.95, tested, 1.0 - gate_probability))
    assert false_alarms(tested, gate_probability, 0.5).at_most == int(
        binom.ppf(0.5, tested, 1.0 - gate_probability))


def test_the_start_of_a_hundred_lane_changes_gates_some_by_chance() -> None:
    """Simulated: 100 runs of 220 gated updates in their first second (steering and wheel
    speeds at 100 Hz, GNSS position and velocity at 10 Hz), each NIS a chi-square draw
    (a consistent filter) against the gate's quantile: the refused count is the gate's false
    alarms, rarely zero, and within the bound in most of 400 such ensembles."""
    rng = np.random.default_rng(8)
    gate = 0.9999
    thresholds = {dof: chi_square_quantile(gate, dof) for dof in (1, 2, 4)}
    dofs = np.repeat([1, 4, 2, 2], [100, 100, 10, 10])
    counts = []
    for _ in range(400):
        nis = rng.chisquare(np.tile(dofs, 100))
        counts.append(int(np.sum(nis > np.array([thresholds[d] for d in np.tile(dofs, 100)]))))
    chance = false_alarms(100 * dofs.size, gate)
    assert np.mean(counts) == pytest.approx(chance.expected, rel=0.15)
    assert np.mean(np.array(counts) == 0) < 0.2
    assert 0.9 <= np.mean(np.array(counts) <= chance.at_most) <= 1.0
    with pytest.raises(ValueError, match="tested"):
        false_alarms(-1, gate)
    with pytest.raises(ValueError, match="gate_probability"):
        false_alarms(10, 1.0)


def test_bad_input_is_refused() -> None:
    t_s = np.arange(10) * 0.5
    with pytest.raises(ValueError, match="columns"):
        ensemble_consistency(t_s, np.ones((2, 9)), [{}, {}], [{}, {}])
    with pytest.raises(ValueError, match="runs"):
        ensemble_consistency(t_s, np.ones((2, 10)), [{}], [{}])
    with pytest.raises(ValueError, match="non-finite"):
        ensemble_consistency(t_s, np.full((2, 10), np.nan), [{}, {}], [{}, {}])


# ------------------------------------------------------------------ closed loop (slow)

SEEDS = range(600, 620)
"""Twenty seeds no other test uses (and neither the tuning set nor the judging set of
bench/estimator_consistency.py)."""
DURATION_S = 15.0
"""The whole lane change: both swerves and the straights between them."""


@pytest.fixture(scope="module", params=[("gnss", "ekf")])
def logged_ensemble(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
                    ) -> tuple[ScenarioConfig, list[EnsembleMember], list[LoggedRun]]:
    """Twenty closed-loop lane changes (the real plant and runner, a sampled initial
    estimate), their ensemble members and their logs."""
    suite, estimator = request.param
    config = load_config("lane-change", overrides=[f"sensors.suite={suite}"],
                         duration_s=DURATION_S, estimator=estimator)
    out = tmp_path_factory.mktemp(f"{suite}-{estimator}")
    workshop = Workshop()  # the runs share their built parts (the same numbers)
    members = [run_member(config, seed, out, keep_log=True, workshop=workshop)
               for seed in SEEDS]
    logs = [logged_run(out / f"{config.name}-{estimator}-{seed}.mcap") for seed in SEEDS]
    return config, members, logs  # each log read once, replayed by every mistuned filter


@pytest.mark.slow
def test_closed_loop_ensemble_is_consistent(
        logged_ensemble: tuple[ScenarioConfig, list[EnsembleMember], list[LoggedRun]]) -> None:
    """Twenty runs of the lane change: ANEES inside its band at >= 90 % of the steps after
    1 s, every sensor's NIS per dof after 1 s in [0.9, 1.1] (both judged once the prior has
    converged; the start-up has its own figure, ``gated_first_s_<sensor>``).
    bench/estimator_consistency.py judges 100 held-out runs in groups of 20."""
    _, members, _ = logged_ensemble
    result = judge(members, settled_nis=True)
    print("\n".join(result.lines()))
    assert set(result.nis) == {"gnss", "imu", "wheel_speed", "steering"}
    assert result.consistent()


@pytest.mark.slow
@pytest.mark.parametrize("q_factor", [0.3, 3.0, 0.01, 100.0])
def test_mistuned_process_noise_fails_the_check(
        logged_ensemble: tuple[ScenarioConfig, list[EnsembleMember], list[LoggedRun]],
        q_factor: float) -> None:
    """The same check fails the same filter with all its process noise x0.3 and x3 (and
    x0.01, x100), replayed over the runs' sensor streams, and on the side the error says:
    too little process noise is over-confident (the ANEES above its band at more steps than
    below); too much is under-confident (below more than above, or a sensor's innovations
    smaller than the filter expects: its NIS per dof under 0.85; with x3 the IMU's and the
    steering's, while the ANEES, pinned by the sensors, hardly leaves its band)."""
    config, _, logs = logged_ensemble
    estimator = scaled_process_noise(config.estimator, q_factor)
    workshop = Workshop()  # one filter, restarted for each run's stream
    members = [replay(dataclasses.replace(config, seed=seed), log, estimator, workshop)
               for seed, log in zip(SEEDS, logs, strict=True)]
    result = judge(members, settled_nis=True)
    print("\n".join(result.lines()))
    assert not result.consistent()
    if q_factor < 1.0:
        assert result.fraction_above > result.fraction_below
    else:
        assert (result.fraction_below > result.fraction_above
                or min(s.nis_per_dof for s in result.nis.values()) < 0.85)
