"""Extremum seeking on static maps with a known optimum, and its tuning rules."""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np
import pytest

from cosim.core.exceptions import ConfigError
from tracker.cruise.esc import (
    EscAdaptation,
    EscChannel,
    EscFilters,
    EscTuningWarning,
    ExtremumSeeker,
    tuning_breaches,
    warn_breaches,
)

DT_S = 0.05
FILTERS = EscFilters(highpass_radps=0.2, lowpass_radps=0.05, plant_frequency_radps=10.0)


def channel(name: str, initial: float, frequency_radps: float, step: float = 2.0,
            amplitude: float = 0.05) -> EscChannel:
    return EscChannel(name=name, initial=initial, low=-10.0, high=10.0, amplitude=amplitude,
                      frequency_radps=frequency_radps, demodulation_amplitude=1.0, step=step)


def seek(seeker: ExtremumSeeker, objective, duration_s: float) -> list[tuple[float, ...]]:
    estimates = []
    for k in range(round(duration_s / DT_S)):
        t_s = k * DT_S
        theta = np.array(seeker.applied(t_s))
        estimates.append(seeker.update(t_s, objective(theta)).estimate)
    return estimates


def test_three_parameters_converge_to_the_minimum_of_a_quadratic_map() -> None:
    optimum = np.array([0.8, -0.4, 1.5])
    weights = np.array([1.0, 2.0, 0.5])

    def objective(theta: np.ndarray) -> float:
        return 3.0 + float(weights @ (theta - optimum) ** 2)

    channels = (channel("k_v", 0.0, 1.0), channel("k_x", 0.5, 1.6), channel("k_vrel", 0.0, 2.3))
    seeker = ExtremumSeeker(channels, FILTERS, DT_S)
    assert not tuning_breaches(channels, FILTERS, DT_S)
    estimates = np.array(seek(seeker, objective, 400.0))
    start_error = np.abs(estimates[0] - optimum)
    final_error = np.abs(estimates[-1] - optimum)
    # Within the perturbation amplitude of the optimum, from errors of 0.4 to 1.5.
    assert np.all(final_error < 0.05), final_error
    assert np.all(start_error > 0.3)
    # Settled: the last 50 s move less than the perturbation amplitude.
    assert np.ptp(estimates[-1000:], axis=0).max() < 0.05


def test_the_seeker_descends_a_non_quadratic_map_to_its_minimum() -> None:
    """A map whose minimum is at theta = ln 2 (J = e^theta - 2 theta)."""
    seeker = ExtremumSeeker((channel("theta", 2.0, 1.3, step=1.0),), FILTERS, DT_S)
    estimates = seek(seeker, lambda theta: math.exp(theta[0]) - 2.0 * theta[0], 400.0)
    assert abs(estimates[-1][0] - math.log(2.0)) < 0.05
    assert abs(estimates[0][0] - math.log(2.0)) > 1.0


def test_a_maximum_repels_it() -> None:
    """Descent, not ascent: on J = -(theta - 1)^2 the estimate moves away from 1."""
    seeker = ExtremumSeeker((channel("theta", 1.2, 1.3),), FILTERS, DT_S)
    estimates = seek(seeker, lambda theta: -float((theta[0] - 1.0) ** 2), 100.0)
    assert estimates[-1][0] > 2.0


def test_bounds_hold_the_estimate() -> None:
    bounded = EscChannel("theta", 0.5, 0.0, 1.0, 0.05, 1.3, 1.0, 2.0)
    seeker = ExtremumSeeker((bounded,), FILTERS, DT_S)
    estimates = seek(seeker, lambda theta: float((theta[0] - 3.0) ** 2), 200.0)
    assert estimates[-1][0] == pytest.approx(1.0)
    assert all(0.0 <= e[0] <= 1.0 for e in estimates)


@pytest.mark.parametrize(("channels", "filters", "rule"), [
    ((channel("a", 0.0, 12.0),), FILTERS, "perturbation slower than the plant"),
    ((channel("a", 0.0, 0.1),), FILTERS, "high-pass cut-off below the perturbation"),
    ((channel("a", 0.0, 1.0),),
     EscFilters(0.1, 2.0, 10.0), "low-pass cut-off below the perturbation'"),
    ((channel("a", 0.0, 1.0, amplitude=0.5),), FILTERS,
     "demodulation amplitude much larger than modulation"),
    ((channel("a", 0.0, 1.0), channel("b", 0.0, 1.0)), FILTERS,
     "distinct perturbation frequencies"),
    ((channel("a", 0.0, 1.0), channel("b", 0.0, 1.04)), FILTERS,
     "low-pass cut-off below the frequency spacing"),
    ((channel("a", 0.0, 1.0), channel("b", 0.0, 2.3), channel("c", 0.0, 3.3)), FILTERS,
     "no frequency the sum of two others"),
    ((channel("a", 0.0, 1.0, step=0.0),), FILTERS, "positive integrator step"),
    ((channel("a", 0.0, 70.0),), EscFilters(0.2, 0.2, 100.0),
     "perturbation below the Nyquist frequency"),
    ((channel("a", 0.0, 1.0), channel("b", 0.0, 2.03)), FILTERS, "no frequency twice another"),
    ((channel("a", 0.0, 1.0), channel("b", 0.0, 1.5), channel("c", 0.0, 2.53)), FILTERS,
     "no frequency the sum of two others"),
    ((dataclasses.replace(channel("a", 0.0, 1.0), plant_frequency_radps=0.8),), FILTERS,
     "perturbation slower than the plant"),
])
def test_each_breached_rule_is_a_warning_that_names_it(channels, filters, rule) -> None:
    with pytest.warns(EscTuningWarning, match=rule):
        warn_breaches(channels, filters, DT_S)


def test_a_good_tuning_warns_nothing() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warn_breaches((channel("a", 0.0, 1.1), channel("b", 0.0, 1.7)), FILTERS, DT_S)


def test_a_channels_own_plant_frequency_replaces_the_shared_one() -> None:
    """The shared plant frequency is 10 rad/s; a channel acting through a 0.8 rad/s mode
    breaches the rule at 1 rad/s, one acting through a 2 rad/s mode does not."""
    slow_mode = dataclasses.replace(channel("a", 0.0, 1.0), plant_frequency_radps=0.8)
    fast_mode = dataclasses.replace(channel("a", 0.0, 1.0), plant_frequency_radps=2.0)
    assert any("0.8 rad/s" in b for b in tuning_breaches((slow_mode,), FILTERS, DT_S))
    assert not tuning_breaches((fast_mode,), FILTERS, DT_S)


# A noisy static map: J = (theta - 2)^2 + 0.05 + theta^2 n^2, n ~ N(0, 1) afresh at every
# sample. E[J] = (theta - 2)^2 + 0.05 + theta^2 is least at theta = 1; E[log J] is least
# near theta = 1.75 (the logarithm discounts the heavy tail of the noise term).
NOISY_MINIMUM = 1.0
NOISY_DURATION_S = 1000.0
LAST_S = 100.0


def seek_noisy(adaptation: EscAdaptation, seed: int, log: bool = False) -> np.ndarray:
    rng = np.random.default_rng(seed)
    noisy = EscChannel("theta", 0.4, 0.0, 3.0, 0.1, 1.3, 1.0, 1.0)
    seeker = ExtremumSeeker((noisy,), FILTERS, DT_S, adaptation)
    estimates = []
    for k in range(round(NOISY_DURATION_S / DT_S)):
        t_s = k * DT_S
        theta = seeker.applied(t_s)[0]
        objective = (theta - 2.0) ** 2 + 0.05 + theta**2 * rng.standard_normal() ** 2
        seek_on = math.log(objective + 0.01) if log else objective
        estimates.append(seeker.update(t_s, seek_on).estimate[0])
    return np.array(estimates)


def last_range(estimates: np.ndarray) -> float:
    return float(np.ptp(estimates[-round(LAST_S / DT_S):]))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_normalised_with_a_decaying_step_it_settles_at_the_minimum_of_the_mean(
        seed: int) -> None:
    estimates = seek_noisy(EscAdaptation(normalise_by_mean=True, step_decay_s=50.0), seed)
    assert abs(estimates[-1] - NOISY_MINIMUM) < 0.15
    assert last_range(estimates) < 0.1


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_with_a_constant_step_it_keeps_wandering_on_a_noisy_map(seed: int) -> None:
    """The same seeker without the decay: its last 100 s span more than 0.3."""
    estimates = seek_noisy(EscAdaptation(normalise_by_mean=True), seed)
    assert last_range(estimates) > 0.3


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_seeking_on_log_j_settles_at_the_minimum_of_the_mean_log_instead(seed: int) -> None:
    estimates = seek_noisy(EscAdaptation(step_decay_s=50.0), seed, log=True)
    assert last_range(estimates) < 0.1
    assert estimates[-1] > NOISY_MINIMUM + 0.3


def test_tuning_resumes_with_a_fresh_high_pass() -> None:
    """A stretch with no active channel (an objective of 10^4, falling) leaves no trace: once
    tuning resumes, the estimates are those of a seeker that never saw it."""
    optimum = 0.8

    def objective(theta: float) -> float:
        return 3.0 + (theta - optimum) ** 2

    fresh = ExtremumSeeker((channel("theta", 0.0, 1.0),), FILTERS, DT_S)
    paused = ExtremumSeeker((channel("theta", 0.0, 1.0),), FILTERS, DT_S)
    for k in range(200):
        paused.update(k * DT_S, 1e4 * math.exp(-k * DT_S), active=(False,))
    for k in range(200, 2000):
        t_s = k * DT_S
        first = fresh.update(t_s, objective(fresh.applied(t_s)[0])).estimate
        second = paused.update(t_s, objective(paused.applied(t_s)[0])).estimate
        assert first == second
    assert abs(first[0] - optimum) < abs(0.0 - optimum)


def test_a_bad_adaptation_is_refused() -> None:
    with pytest.raises(ConfigError, match="step decay 0"):
        EscAdaptation(step_decay_s=0.0)
    with pytest.raises(ConfigError, match="mean floor -1"):
        EscAdaptation(mean_floor=-1.0)


def test_a_channels_own_low_pass_is_checked_against_its_neighbours() -> None:
    """The shared low-pass (0.05 rad/s) is below the 0.1 rad/s spacing; a channel of its own
    at 0.12 rad/s is not, and the breach names it."""
    fast = dataclasses.replace(channel("b", 0.0, 1.1), lowpass_radps=0.12)
    breaches = tuning_breaches((channel("a", 0.0, 1.0), fast), FILTERS, DT_S)
    assert len(breaches) == 1
    assert "b omega_l = 0.12 rad/s >= |omega_a - omega_b|" in breaches[0]
    assert not tuning_breaches((channel("a", 0.0, 1.0), channel("b", 0.0, 1.1)), FILTERS, DT_S)
