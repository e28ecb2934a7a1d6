"""The UKF and the EKF agree where the problem is mildly nonlinear.

Same state, same CasADi models, same data: on the synthetic lane change (the tanh tyres
give 4 % less force than linear ones at the peak) and on a hard one (0.7 g, the tyres well
into saturation), the two means differ by a small fraction of a standard deviation at every
time, and their standard deviations by less than one per cent. The states are well
observed, so the linearisation error the UKF avoids is small: agreement is the expected
result, and a disagreement would point to a bug in one of them.
"""

from __future__ import annotations

import numpy as np
import pytest

from estimation.state import STATE_NAMES
from tests.estimation.drive import Run, SensorSetup, lane_change, run_filter


def _compare(ekf: Run, ukf: Run) -> tuple[np.ndarray, np.ndarray]:
    """Per state, after the first second: the largest |mean difference| / EKF sigma, and the
    largest |UKF sigma / EKF sigma - 1|."""
    sigma_ekf = np.sqrt(np.einsum("kii->ki", ekf.covariances))
    sigma_ukf = np.sqrt(np.einsum("kii->ki", ukf.covariances))
    settled = ekf.settled()
    mean_gap = (np.abs(ukf.means - ekf.means) / sigma_ekf)[settled].max(axis=0)
    sigma_gap = np.abs(sigma_ukf / sigma_ekf - 1.0)[settled].max(axis=0)
    return mean_gap, sigma_gap


@pytest.mark.parametrize(
    ("peak_steer_rad", "gnss_sigma_m"), [(0.045, 0.02), (0.045, 0.5), (0.12, 0.5)]
)
@pytest.mark.slow
def test_ukf_agrees_with_ekf(peak_steer_rad: float, gnss_sigma_m: float) -> None:
    profile = lane_change(peak_steer_rad)
    setup = SensorSetup(gnss_sigma_m=gnss_sigma_m, gyro_bias_radps=0.002, ax_bias_mps2=0.02)
    ekf = run_filter(profile, estimator="ekf", setup=setup)
    ukf = run_filter(profile, estimator="ukf", setup=setup)
    mean_gap, sigma_gap = _compare(ekf, ukf)
    peak_ay = np.abs(ekf.truth.values["ay_mps2"]).max()
    worst = STATE_NAMES[int(np.argmax(mean_gap))]
    print(f"peak a_y {peak_ay:.1f} m/s^2, GNSS {gnss_sigma_m} m: largest mean gap "
          f"{mean_gap.max():.3f} sigma ({worst}), largest sigma gap {sigma_gap.max():.4f}")
    assert mean_gap.max() < 0.1
    assert sigma_gap.max() < 0.01
    for name in ("x_m", "yaw_rad", "vx_mps", "vy_mps"):
        assert ukf.rmse(name) == pytest.approx(ekf.rmse(name), rel=0.05), name
    assert ukf.counts == ekf.counts
