"""The EKF on simulated drives: accuracy, consistency, outliers, dropouts, determinism.

The truth comes from the kinematic equations (tests/estimation/drive.py), the sensors from a
seeded generator. Figures are printed (``pytest -s``) so they can be quoted.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from estimation.models import STATE_NAMES
from tests.estimation.drive import (
    NEES_STATES,
    Run,
    SensorSetup,
    circle,
    lane_change,
    run_filter,
)

RTK_SIGMA_M = 0.02
COARSE_SIGMA_M = 0.5


def _figures(label: str, run: Run) -> str:
    nees = run.nees()[run.settled()]
    nis = ", ".join(f"{s} {np.mean(v):.2f}" for s, v in sorted(run.nis.items()))
    return (
        f"{label}: position RMSE {run.position_rmse_m():.4f} m, yaw RMSE "
        f"{run.rmse('yaw_rad'):.4f} rad, vx RMSE {run.rmse('vx_mps'):.4f} m/s, "
        f"NEES({len(NEES_STATES)}) mean {nees.mean():.2f}, NIS mean: {nis}"
    )


def _rejections(run: Run) -> int:
    return sum(v for c in run.counts.values() for k, v in c.items() if k.startswith("rejected"))


@pytest.fixture(scope="module")
def lane_change_rtk() -> Run:
    return run_filter(lane_change(), setup=SensorSetup(gnss_sigma_m=RTK_SIGMA_M))


@pytest.fixture(scope="module")
def lane_change_coarse() -> Run:
    return run_filter(lane_change(), setup=SensorSetup(gnss_sigma_m=COARSE_SIGMA_M))


def test_lane_change_with_rtk_gnss(lane_change_rtk: Run) -> None:
    run = lane_change_rtk
    print(_figures("lane change, RTK GNSS", run))
    # Per axis the filter beats the GNSS alone clearly (sigma per axis, sqrt(2) sigma in 2D).
    assert run.position_rmse_m() < 0.75 * math.sqrt(2) * RTK_SIGMA_M
    assert run.rmse("yaw_rad") < 0.005
    assert run.rmse("vx_mps") < 0.02
    assert run.rmse("yaw_rate_radps") < 0.005
    assert _rejections(run) == 0
    assert run.counts["gnss"]["accepted"] == 150


def test_lane_change_with_coarse_gnss(lane_change_coarse: Run) -> None:
    run = lane_change_coarse
    print(_figures("lane change, 0.5 m GNSS", run))
    assert run.position_rmse_m() < 0.4 * math.sqrt(2) * COARSE_SIGMA_M
    assert run.rmse("yaw_rad") < 0.01
    assert _rejections(run) == 0


@pytest.mark.parametrize("fixture", ["lane_change_rtk", "lane_change_coarse"])
def test_filter_is_consistent(fixture: str, request: pytest.FixtureRequest) -> None:
    """NEES over (x, y, yaw, vx) averaged over time in a plausible band for 4 DoF; NIS too.

    The process noise covers a real car's unmodelled motion, so on this model-consistent
    truth the filter is somewhat conservative (NEES below 4), never overconfident.
    """
    run: Run = request.getfixturevalue(fixture)
    nees = run.nees()[run.settled()]
    assert 1.0 < nees.mean() < 12.0
    assert np.percentile(nees, 99) < 30.0
    gnss_nis = np.mean(run.nis["gnss"])
    assert 0.5 * 2 < gnss_nis < 2.0 * 2  # dim 2


def test_circle() -> None:
    for sigma in (RTK_SIGMA_M, COARSE_SIGMA_M):
        run = run_filter(circle(), setup=SensorSetup(gnss_sigma_m=sigma))
        print(_figures(f"circle R 40 m at 15 m/s, GNSS {sigma} m", run))
        assert run.position_rmse_m() < 0.75 * math.sqrt(2) * sigma
        assert run.rmse("yaw_rad") < 0.01
        assert 1.0 < run.nees()[run.settled()].mean() < 12.0
        assert _rejections(run) == 0


def test_sideslip_is_estimated_not_mistaken_for_heading() -> None:
    """A car slipping sideways: course differs from heading by up to ~0.04 rad.

    The lateral-velocity state takes the difference; the heading stays close to the truth,
    and the RTK fixes keep passing the gate.
    """
    run = run_filter(circle(sideslip_gain_s=0.1), setup=SensorSetup(gnss_sigma_m=RTK_SIGMA_M))
    print(_figures("circle with sideslip, RTK GNSS", run))
    sideslip = np.abs(run.truth.values["vy_mps"] / run.truth.values["vx_mps"]).max()
    assert sideslip > 0.03
    assert run.rmse("yaw_rad") < 0.25 * sideslip
    assert run.rmse("vy_mps") < 0.2
    assert run.position_rmse_m() < math.sqrt(2) * RTK_SIGMA_M
    assert _rejections(run) == 0


def test_rolling_radius_mismatch_is_learned() -> None:
    """The tyres roll on a radius 2 % below the belief (the MuJoCo sedan's is ~0.2 %).

    Without the rolling-radius state the wheel speeds would bias vx by 2 %; the GNSS makes
    the scale observable and the filter learns it.
    """
    setup = SensorSetup(gnss_sigma_m=RTK_SIGMA_M, rolling_radius_scale=0.98)
    run = run_filter(lane_change(), setup=setup)
    scale = STATE_NAMES.index("rolling_radius_scale")
    estimate, sigma = run.means[-1, scale], math.sqrt(run.covariances[-1][scale, scale])
    print(f"rolling radius scale 0.98 -> estimated {estimate:.5f} +- {sigma:.5f}")
    assert abs(estimate - 0.98) < 3 * sigma
    assert sigma < 0.002
    assert run.rmse("vx_mps", run.t_s > 5.0) < 0.02
    assert 1.0 < run.nees()[run.settled()].mean() < 12.0
    assert _rejections(run) == 0


def test_outlier_and_nan_are_rejected_and_counted() -> None:
    setup = SensorSetup(gnss_sigma_m=RTK_SIGMA_M, gnss_outlier_at_s=6.0, nan_imu_at_s=7.0)
    run = run_filter(lane_change(), setup=setup)
    assert run.counts["gnss"]["rejected_gate"] == 1
    assert run.counts["imu"]["rejected_nonfinite"] == 1
    assert _rejections(run) == 2
    assert [(t, sensor) for t, sensor, _ in run.reasons] == [(6.0, "gnss"), (7.0, "imu")]
    assert np.isfinite(run.means).all() and np.isfinite(run.covariances).all()
    error = np.hypot(run.error("x_m"), run.error("y_m"))
    assert error[run.t_s >= 5.9].max() < 0.1  # the 20 m jump left no trace


def test_gnss_dropout_of_three_seconds() -> None:
    """Dead reckoning on gyro and wheel speeds through the lane change's first swerve."""
    setup = SensorSetup(gnss_sigma_m=RTK_SIGMA_M, gnss_outage_s=(4.0, 7.0))
    run = run_filter(lane_change(), setup=setup)
    error = np.hypot(run.error("x_m"), run.error("y_m"))
    outage = (run.t_s >= 4.0) & (run.t_s < 7.0)
    print(f"GNSS dropout 4-7 s: max position error {error[outage].max():.3f} m")
    assert error[outage].max() < 1.0
    # The filter knows it is less sure while blind, and recovers afterwards.
    x = 0
    sigma = np.sqrt(run.covariances[:, x, x])
    assert sigma[outage][-1] > 3.0 * sigma[run.t_s < 4.0][-1]
    assert sigma[run.t_s >= 8.0][0] < 1.5 * sigma[run.t_s < 4.0][-1]
    assert _rejections(run) == 0


def test_gnss_only_still_works() -> None:
    """GNSS alone makes every state observable (the EKF's only required sensor)."""
    setup = SensorSetup(gnss_sigma_m=RTK_SIGMA_M, use_imu=False, use_wheels=False)
    run = run_filter(lane_change(), setup=setup)
    print(_figures("lane change, RTK GNSS only", run))
    assert run.position_rmse_m() < 3 * RTK_SIGMA_M
    assert run.rmse("vx_mps") < 0.5
    assert run.rmse("yaw_rad") < 0.05


def test_runs_are_deterministic() -> None:
    first = run_filter(lane_change(), seed=11)
    second = run_filter(lane_change(), seed=11)
    other = run_filter(lane_change(), seed=12)
    np.testing.assert_array_equal(first.means, second.means)
    np.testing.assert_array_equal(first.covariances, second.covariances)
    assert first.counts == second.counts
    assert not np.array_equal(first.means, other.means)
