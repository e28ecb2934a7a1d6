"""Extremum seeking on static maps with a known optimum, and its tuning rules."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from tracker.esc import (
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
    ((channel("a", 0.0, 1.0), channel("b", 0.0, 2.0), channel("c", 0.0, 3.0)), FILTERS,
     "no frequency the sum of two others"),
    ((channel("a", 0.0, 1.0, step=0.0),), FILTERS, "positive integrator step"),
    ((channel("a", 0.0, 70.0),), EscFilters(0.2, 0.2, 100.0),
     "perturbation below the Nyquist frequency"),
])
def test_each_breached_rule_is_a_warning_that_names_it(channels, filters, rule) -> None:
    with pytest.warns(EscTuningWarning, match=rule):
        warn_breaches(channels, filters, DT_S)


def test_a_good_tuning_warns_nothing() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warn_breaches((channel("a", 0.0, 1.1), channel("b", 0.0, 1.7)), FILTERS, DT_S)
