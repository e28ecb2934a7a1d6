"""Both filters on simulated drives: accuracy, consistency, biases, side slip, faults.

The truth is a dynamic bicycle driven by prescribed steering (tests/estimation/drive.py),
the sensors come from a seeded generator. Figures are printed (``pytest -s``) so they can be
quoted.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosim.core.initial_state import InitialState
from cosim.core.vehicle_params import VehicleParams
from estimation.belief_models import process_noise, roll_params
from estimation.bicycle import BicycleParams
from estimation.config import EstimatorConfig
from estimation.process_model import ProcessModel
from estimation.state import STATE_NAMES, state_index
from tests.estimation.drive import (
    NEES_STATES,
    Run,
    SensorSetup,
    circle,
    lane_change,
    run_filter,
    simulate_truth,
)

RTK_SIGMA_M = 0.02
COARSE_SIGMA_M = 0.5
FILTERS = ("ekf", pytest.param("ukf", marks=pytest.mark.slow))
"""The UKF's closed-loop drives cost twice the EKF's: they run in ``make test``, not in
``make test-fast``."""


def _figures(label: str, run: Run) -> str:
    nees = run.nees()[run.settled()]
    nis = ", ".join(f"{s} {np.mean(v):.2f}" for s, v in sorted(run.nis.items()))
    return (
        f"{label}: position RMSE {run.position_rmse_m():.4f} m, yaw RMSE "
        f"{run.rmse('yaw_rad'):.4f} rad, vx RMSE {run.rmse('vx_mps'):.4f} m/s, vy RMSE "
        f"{run.rmse('vy_mps'):.4f} m/s, NEES({len(NEES_STATES)}) mean {nees.mean():.2f}, "
        f"NIS mean: {nis}"
    )


def _rejections(run: Run) -> int:
    return sum(v for c in run.counts.values() for k, v in c.items() if k.startswith("rejected"))


@pytest.fixture(scope="module", params=FILTERS)
def name(request: pytest.FixtureRequest) -> str:
    return request.param


@pytest.fixture(scope="module")
def lane_change_rtk(name: str) -> Run:
    return run_filter(lane_change(), estimator=name, setup=SensorSetup(gnss_sigma_m=RTK_SIGMA_M))


@pytest.fixture(scope="module")
def lane_change_coarse(name: str) -> Run:
    return run_filter(
        lane_change(), estimator=name, setup=SensorSetup(gnss_sigma_m=COARSE_SIGMA_M)
    )


def test_lane_change_with_rtk_gnss(lane_change_rtk: Run, name: str) -> None:
    run = lane_change_rtk
    print(_figures(f"{name}, lane change, RTK GNSS", run))
    # Per axis the filter beats the GNSS alone clearly (sigma per axis, sqrt(2) sigma in 2D).
    assert run.position_rmse_m() < 0.75 * math.sqrt(2) * RTK_SIGMA_M
    assert run.rmse("yaw_rad") < 0.002
    assert run.rmse("vx_mps") < 0.02
    assert run.rmse("vy_mps") < 0.03
    assert run.rmse("yaw_rate_radps") < 0.005
    assert _rejections(run) == 0
    assert run.counts["gnss"]["accepted"] == 150
    assert run.counts["steering"]["accepted"] == 1500


def test_lane_change_with_coarse_gnss(lane_change_coarse: Run, name: str) -> None:
    run = lane_change_coarse
    print(_figures(f"{name}, lane change, 0.5 m GNSS", run))
    assert run.position_rmse_m() < 0.3 * math.sqrt(2) * COARSE_SIGMA_M
    assert run.rmse("yaw_rad") < 0.008
    assert _rejections(run) == 0


@pytest.mark.parametrize("fixture", ["lane_change_rtk", "lane_change_coarse"])
def test_filter_is_consistent(fixture: str, name: str, request: pytest.FixtureRequest) -> None:
    """NEES over (x, y, yaw, vx) averaged over time in a plausible band for 4 DoF; NIS too.

    The process noise covers the real car's unmodelled motion (tuned on the MuJoCo plant),
    so on this model-consistent truth the filter is conservative (NEES below 4), never
    overconfident.
    """
    run: Run = request.getfixturevalue(fixture)
    nees = run.nees()[run.settled()]
    assert 0.5 < nees.mean() < 6.0
    assert np.percentile(nees, 99) < 20.0
    gnss_nis = np.mean(run.nis["gnss"])
    assert 0.5 * 2 < gnss_nis < 2.0 * 2  # dim 2


def test_circle(name: str) -> None:
    for sigma in (RTK_SIGMA_M, COARSE_SIGMA_M):
        run = run_filter(circle(duration_s=12.0), estimator=name,
                         setup=SensorSetup(gnss_sigma_m=sigma))
        print(_figures(f"{name}, circle 0.06 rad at 15 m/s, GNSS {sigma} m", run))
        assert run.position_rmse_m() < 0.75 * math.sqrt(2) * sigma
        assert run.rmse("yaw_rad") < 0.01
        assert 0.5 < run.nees()[run.settled()].mean() < 6.0
        assert _rejections(run) == 0


def test_constant_gyro_bias_is_learned_within_seconds(name: str) -> None:
    """A gyro bias of 0.003 rad/s (1.5 times the sensor's turn-on spread) and an
    accelerometer bias of 0.03 m/s^2: after 5 s of driving with RTK GNSS the gyro bias is
    known to 15 % (the heading's own random walk, ``yaw_psd_rad2ps``, takes part of it early),
    the speed unbiased; with GNSS, IMU and steering alone (no wheel speeds)
    to 20 % after 6 s."""
    bias_radps = 0.003
    for setup, after_s, tolerance in (
        (SensorSetup(gyro_bias_radps=bias_radps, ax_bias_mps2=0.03), 5.0, 0.15),
        (SensorSetup(gyro_bias_radps=bias_radps, ax_bias_mps2=0.03, use_wheels=False), 6.0, 0.2),
    ):
        run = run_filter(lane_change(), estimator=name, setup=setup)
        estimate = run.state("gyro_bias_radps")
        later = run.t_s >= after_s
        print(f"{name}, gyro bias {bias_radps} rad/s, wheels {setup.use_wheels}: estimate at "
              f"{after_s:g} s {estimate[later][0]:.5f}, at the end {estimate[-1]:.5f} "
              f"+- {run.sigma('gyro_bias_radps')[-1]:.5f}")
        # It starts from zero (the first log follows the first IMU updates) ...
        assert abs(estimate[0]) < 0.2 * bias_radps
        assert np.abs(estimate[later] - bias_radps).max() < tolerance * bias_radps  # ... learns
        assert np.abs(estimate[later] - bias_radps).max() < 3 * run.sigma("gyro_bias_radps")[-1]
        assert run.rmse("yaw_rate_radps", later) < 0.004  # the bias is not in the yaw rate
        assert abs(run.state("ax_bias_mps2")[-1] - 0.03) < 0.01
        assert run.rmse("vx_mps", later) < 0.03
        assert _rejections(run) == 0


def test_lateral_accelerometer_bias_is_not_read_as_a_yaw_rate(name: str) -> None:
    """A lateral accelerometer bias of 0.03 m/s^2 (1.5 times the sensor's turn-on spread)
    with a 0.5 m GNSS, where the heading is weakly observed: ``a_y = vy' + r vx + b_y``, so
    a filter without ``ay_bias_mps2`` reads the bias as a yaw rate of ``b_y / vx`` (2e-3
    rad/s at the drive's 15 m/s) and its gyro-bias estimate takes the opposite. With the
    state, the gyro-bias estimate stays within half of that of the truth (zero) and the ay
    bias is learned."""
    ay_bias_mps2 = 0.03
    setup = SensorSetup(gnss_sigma_m=COARSE_SIGMA_M, ay_bias_mps2=ay_bias_mps2)
    run = run_filter(lane_change(), estimator=name, setup=setup)
    later = run.t_s >= 5.0
    gyro_bias = run.state("gyro_bias_radps")[later]
    ay_bias = run.state("ay_bias_mps2")
    print(f"{name}, ay bias {ay_bias_mps2} m/s^2: gyro bias estimate after 5 s within "
          f"{np.abs(gyro_bias).max():.2e} rad/s of 0, ay bias at the end {ay_bias[-1]:.4f} "
          f"+- {run.sigma('ay_bias_mps2')[-1]:.4f}")
    speed_mps = run.state("vx_mps")[later].mean()
    assert np.abs(gyro_bias).max() < 0.5 * ay_bias_mps2 / speed_mps
    assert abs(ay_bias[-1] - ay_bias_mps2) < 0.01
    assert abs(ay_bias[-1] - ay_bias_mps2) < 3 * run.sigma("ay_bias_mps2")[-1]
    assert run.rmse("yaw_rate_radps", later) < 0.004
    assert _rejections(run) == 0


def test_gnss_velocity_observes_the_heading(name: str) -> None:
    """With a 0.5 m receiver the heading is seen only through the track of positions; its
    Doppler velocity (0.05 m/s, 0.15 deg of course at 20 m/s) sees the course directly: the
    heading error falls by more than half, and the filter stays consistent."""
    without = run_filter(lane_change(), estimator=name,
                         setup=SensorSetup(gnss_sigma_m=COARSE_SIGMA_M))
    with_doppler = run_filter(lane_change(), estimator=name, setup=SensorSetup(
        gnss_sigma_m=COARSE_SIGMA_M, gnss_velocity_sigma_mps=0.05))
    settled = with_doppler.settled()
    print(f"{name}, 0.5 m GNSS: yaw RMSE {without.rmse('yaw_rad', settled):.5f} rad, with "
          f"Doppler {with_doppler.rmse('yaw_rad', settled):.5f} rad; NIS/dof of the velocity "
          f"{np.mean(with_doppler.nis['gnss_velocity']) / 2:.2f}")
    assert with_doppler.rmse("yaw_rad", settled) < 0.5 * without.rmse("yaw_rad", settled)
    assert 0.7 < np.mean(with_doppler.nis["gnss_velocity"]) / 2 < 1.4
    assert 0.5 < with_doppler.nees()[settled].mean() < 6.0
    assert _rejections(with_doppler) == 0


def test_process_model_predicts_side_slip_from_the_steering() -> None:
    """Open loop, no measurement: the filter's process model, fed the steering angle (its
    ``steer_rad`` state set to the truth's every 10 ms) and the truth's ax, predicts the side
    slip, yaw rate and roll of the dynamic-bicycle drive over the whole lane change."""
    belief = VehicleParams()
    profile = lane_change(0.06)
    truth = simulate_truth(profile, InitialState(speed_mps=profile.speed0_mps), belief)
    config = EstimatorConfig()
    process = ProcessModel(
        process_noise(config), BicycleParams.from_vehicle(belief, roll=roll_params(config, belief)),
        config.lateral_residual_time_constant_s,
    )
    x = np.zeros(len(STATE_NAMES))
    x[state_index("vx_mps")] = profile.speed0_mps
    x[state_index("rolling_radius_scale")] = 1.0
    x[state_index("wheel_track_scale")] = 1.0
    predicted, true = [], []
    for index_ms in range(0, len(truth.t_s) - 10, 10):
        x[state_index("steer_rad")] = truth.at(index_ms + 5, "steer_rad")  # mid-step
        x[state_index("ax_mps2")] = truth.at(index_ms + 5, "ax_mps2")
        x = process.step(x, 0.01)[0].reshape(-1)
        predicted.append([x[state_index(n)] for n in ("vy_mps", "yaw_rate_radps", "roll_rad")])
        true.append([truth.at(index_ms + 10, n) for n in ("vy_mps", "yaw_rate_radps", "roll_rad")])
    error = np.array(predicted) - np.array(true)
    vy_true = np.array(true)[:, 0]
    print(f"open-loop side slip: |vy| up to {np.abs(vy_true).max():.3f} m/s, prediction "
          f"error RMS {np.sqrt(np.mean(error[:, 0] ** 2)):.5f} m/s")
    assert np.abs(vy_true).max() > 0.25
    assert np.abs(error[:, 0]).max() < 0.01 * np.abs(vy_true).max()
    assert np.abs(error[:, 1]).max() < 0.01 * np.abs(np.array(true)[:, 1]).max()
    assert np.abs(error[:, 2]).max() < 0.01 * np.abs(np.array(true)[:, 2]).max()


def test_side_slip_follows_the_steering_without_an_imu(name: str) -> None:
    """No gyro, no accelerometer: the side slip comes from the steering through the tyre
    model. With the steering sensor the vy error is a small fraction of vy; without it (the
    steering angle left to a random walk driven by GNSS and wheel speeds) at least twice
    as large."""
    profile = lane_change(0.06)
    with_steering = run_filter(profile, estimator=name, setup=SensorSetup(
        gnss_sigma_m=COARSE_SIGMA_M, use_imu=False))
    without = run_filter(profile, estimator=name, setup=SensorSetup(
        gnss_sigma_m=COARSE_SIGMA_M, use_imu=False, use_steering=False))
    vy_rms = float(np.sqrt(np.mean(with_steering.truth.values["vy_mps"] ** 2)))
    print(f"{name}: vy RMS {vy_rms:.3f} m/s; vy RMSE with steering "
          f"{with_steering.rmse('vy_mps'):.4f}, without {without.rmse('vy_mps'):.4f} m/s")
    assert with_steering.counts["steering"]["accepted"] == 1500
    assert with_steering.rmse("vy_mps") < 0.1 * vy_rms
    assert without.rmse("vy_mps") > 2.0 * with_steering.rmse("vy_mps")
    assert _rejections(with_steering) == 0


def test_rolling_radius_mismatch_is_learned(name: str) -> None:
    """The tyres roll on a radius 2 % below the belief (the MuJoCo sedan's is ~0.3 %).

    Without the rolling-radius state the wheel speeds would bias vx by 2 %; the GNSS makes
    the scale observable and the filter learns it.
    """
    setup = SensorSetup(gnss_sigma_m=RTK_SIGMA_M, rolling_radius_scale=0.98)
    run = run_filter(lane_change(), estimator=name, setup=setup)
    scale = run.state("rolling_radius_scale")[-1]
    sigma = run.sigma("rolling_radius_scale")[-1]
    print(f"{name}: rolling radius scale 0.98 -> estimated {scale:.5f} +- {sigma:.5f}")
    assert abs(scale - 0.98) < 3 * sigma
    assert sigma < 0.002
    assert run.rmse("vx_mps", run.t_s > 5.0) < 0.02
    assert 0.5 < run.nees()[run.settled()].mean() < 6.0
    assert _rejections(run) == 0


def test_gnss_outlier_and_imu_nan_are_rejected_counted_and_leave_no_trace(name: str) -> None:
    """A 20 m GNSS jump at 6 s and a NaN IMU sample at 7 s: both rejected and counted. The
    estimates are exactly those of the same drive with that fix missing (the filter never
    touched the outlier) and within centimetres of the drive without either fault (one fix
    and one IMU sample fewer): the estimate moves by far less than 0.2 m."""
    clean = run_filter(lane_change(), estimator=name, setup=SensorSetup())
    missing = run_filter(lane_change(), estimator=name,
                         setup=SensorSetup(gnss_outage_s=(6.0, 6.05), nan_imu_at_s=7.0))
    setup = SensorSetup(gnss_outlier_at_s=6.0, nan_imu_at_s=7.0)
    run = run_filter(lane_change(), estimator=name, setup=setup)
    assert run.counts["gnss"]["rejected_gate"] == 1
    assert run.counts["gnss"]["channels_gated"] == 2
    assert run.counts["imu"]["rejected_nonfinite"] == 1
    assert _rejections(run) == 2
    assert [(t, sensor, reason) for t, sensor, reason in run.reasons] == [
        (6.0, "gnss", "gate"), (7.0, "imu", "non-finite")]
    assert np.isfinite(run.means).all() and np.isfinite(run.covariances).all()
    np.testing.assert_array_equal(run.means, missing.means)
    moved = np.hypot(run.state("x_m") - clean.state("x_m"), run.state("y_m") - clean.state("y_m"))
    print(f"{name}: estimate moved by at most {moved.max():.4f} m")
    assert moved.max() < 0.05
    assert run.position_error_m()[run.t_s >= 5.9].max() < 0.1


def test_gnss_dropout_of_three_seconds_mid_manoeuvre(name: str) -> None:
    """Dead reckoning on gyro, wheel speeds and steering through the lane change's first
    swerve (GNSS silent 4-7 s): position error below 1 m throughout; within 2 s after the
    fixes return the filter is back to its accuracy and confidence from before."""
    setup = SensorSetup(gnss_sigma_m=RTK_SIGMA_M, gnss_outage_s=(4.0, 7.0))
    run = run_filter(lane_change(), estimator=name, setup=setup)
    error = run.position_error_m()
    sigma = run.sigma("x_m")
    outage = (run.t_s >= 4.0) & (run.t_s < 7.0)
    before = (run.t_s >= 3.0) & (run.t_s < 4.0)
    recovered = run.t_s >= 9.0
    print(f"{name}, GNSS dropout 4-7 s: max position error {error[outage].max():.3f} m, "
          f"after 9 s {error[recovered].max():.3f} m (before {error[before].max():.3f} m)")
    assert error[outage].max() < 1.0
    # The filter knows it is less sure while blind ...
    assert sigma[outage][-1] > 3.0 * sigma[before][-1]
    # ... and 2 s after the fixes return it is as accurate and as sure as before.
    assert sigma[recovered].max() < 1.5 * sigma[before].max()
    assert error[recovered].max() < 2.0 * max(error[before].max(), 3 * RTK_SIGMA_M)
    assert _rejections(run) == 0


def test_gnss_only_still_works(name: str) -> None:
    """GNSS alone makes every vehicle state observable (the filters' only required sensor)."""
    setup = SensorSetup(gnss_sigma_m=RTK_SIGMA_M, use_imu=False, use_wheels=False,
                        use_steering=False)
    run = run_filter(lane_change(), estimator=name, setup=setup)
    print(_figures(f"{name}, lane change, RTK GNSS only", run))
    assert run.position_rmse_m() < 3 * RTK_SIGMA_M
    assert run.rmse("vx_mps") < 0.5
    assert run.rmse("yaw_rad") < 0.05


def test_runs_are_deterministic(name: str) -> None:
    profile = circle(duration_s=4.0)
    first = run_filter(profile, estimator=name, seed=11)
    second = run_filter(profile, estimator=name, seed=11)
    other = run_filter(profile, estimator=name, seed=12)
    np.testing.assert_array_equal(first.means, second.means)
    np.testing.assert_array_equal(first.covariances, second.covariances)
    assert first.counts == second.counts
    assert not np.array_equal(first.means, other.means)
