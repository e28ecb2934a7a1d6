"""The chi-square band of the average NEES and the Monte Carlo summary (estimation/consistency.py),
and a small closed-loop Monte Carlo of both filters (slow)."""

from __future__ import annotations

from pathlib import Path

import pytest

from cosim.simulation.runner import run
from cosim.simulation.scenario_config import load_config
from estimation.consistency import NEES_DOF, nees_band, summarise


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
    with pytest.raises(ValueError):
        nees_band(0, 3)
    with pytest.raises(ValueError):
        nees_band(4, 3, probability=1.5)


def test_summary_of_runs() -> None:
    metrics = [
        {"nees_mean": 3.0, "nis_mean": 1.0, "est_pos_rmse_m": 0.3, "est_yaw_rmse_rad": 0.01,
         "est_speed_rmse_mps": 0.1},
        {"nees_mean": 5.0, "nis_mean": 0.8, "est_pos_rmse_m": 0.4, "est_yaw_rmse_rad": 0.02,
         "est_speed_rmse_mps": 0.1},
    ]
    summary = summarise("ekf", metrics)
    assert summary.runs == 2 and summary.nees_mean == 4.0 and summary.consistent
    assert summary.pos_rmse_m == pytest.approx(0.5**0.5 * 0.5)  # RMS of 0.3 and 0.4
    assert summary.nees_band == nees_band(NEES_DOF, 2)
    assert "inside" in "\n".join(summary.lines())
    with pytest.raises(ValueError, match="nees_mean"):
        summarise("ekf", [{**metrics[0], "nees_mean": float("nan")}])
    with pytest.raises(ValueError):
        summarise("ekf", [])


@pytest.mark.slow
@pytest.mark.parametrize("estimator", ["ekf", "ukf"])
def test_closed_loop_monte_carlo_is_consistent(estimator: str, tmp_path: Path) -> None:
    """Four seeds of the lane change's first 6 s with the 0.5 m GNSS suite, the real plant
    and runner (bench/estimator_consistency.py runs the full 20 x 15 s): the average NEES
    over (x, y, yaw, vx) lies in the 95 % band for 4 runs, the position error is well below
    the GNSS's."""
    metrics = []
    for seed in range(4):
        config = load_config("lane-change", overrides=["sensors.suite=gnss"], seed=seed,
                             duration_s=6.0, estimator=estimator)
        result = run(config, tmp_path / f"{seed}.mcap")
        assert result.completed
        metrics.append(result.metrics)
    summary = summarise(estimator, metrics)
    print("\n".join(summary.lines()))
    assert summary.consistent
    assert summary.pos_rmse_m < 0.5 * 0.5
