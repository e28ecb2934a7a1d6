"""The estimator's configuration: all of its process noise scaled at once (estimation/config.py)."""

from __future__ import annotations

import dataclasses

import pytest

from estimation.config import EstimatorConfig, scaled_process_noise
from estimation.fusion import process_noise


@pytest.mark.parametrize("factor", [0.3, 3.0])
def test_scaled_process_noise_scales_every_psd_of_the_filter(factor: float) -> None:
    """Every PSD the filter's ``Q`` is built from (``estimation.fusion.process_noise``: the
    configured ones, the lateral residual's from its sigma, the bias walks from theirs) is
    ``factor`` times the unscaled one; nothing else changes."""
    config = EstimatorConfig()
    scaled = scaled_process_noise(config, factor)
    before, after = dataclasses.asdict(process_noise(config)), \
        dataclasses.asdict(process_noise(scaled))
    assert set(before) == set(after)
    for name, value in before.items():
        assert after[name] == pytest.approx(factor * value, rel=1e-12), name
    assert any(value > 0.0 for value in before.values())
    assert scaled.noise.gyro_sigma_radps == config.noise.gyro_sigma_radps
    assert scaled.init_position_sigma_m == config.init_position_sigma_m
    assert scaled_process_noise(config, 1.0) == config


@pytest.mark.parametrize("factor", [0.0, -1.0, float("nan")])
def test_scaled_process_noise_refuses_a_factor_that_is_not_positive(factor: float) -> None:
    with pytest.raises(ValueError, match="expected a positive number"):
        scaled_process_noise(EstimatorConfig(), factor)
