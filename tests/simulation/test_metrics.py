"""Per-sensor NIS after settling and the gating at start-up and over the run
(cosim/simulation/metrics.py)."""

from __future__ import annotations

import numpy as np
import pytest

from cosim.core.records import Estimate, VehicleState
from cosim.simulation.metric_keys import undocumented
from cosim.simulation.metrics import MetricsAccumulator
from estimation.consistency import SETTLE_S
from estimation.update_result import ACCEPTED, GATE, PARTIAL, UpdateResult
from tracker.paths.reference_path import ReferencePath


def _accumulator() -> MetricsAccumulator:
    x = np.linspace(0.0, 100.0, 101)
    return MetricsAccumulator(ReferencePath(x, np.zeros_like(x), 10.0))


def test_settled_nis_leaves_out_the_first_second_and_counts_its_gating() -> None:
    """Two-channel updates of NIS 8 (4 per dof, two gated) before the settling time and of
    NIS 2 (1 per dof) after it: ``nis_<sensor>`` mixes them, ``nis_settled_<sensor>`` is 1,
    and the two gated start-up updates are counted among the three tested then; a sensor
    gated only after settling counts 0 gated of its one tested start-up update."""
    metrics = _accumulator()
    early = [UpdateResult(False, 8.0, 2, GATE, 8.0, 2), UpdateResult(True, 4.0, 1, PARTIAL, 8.0, 2),
             UpdateResult(True, 8.0, 2, ACCEPTED, 8.0, 2)]
    for k, update in enumerate(early):
        metrics.add_update("gnss", update, 0.1 * k)
    for k in range(9):
        metrics.add_update("gnss", UpdateResult(True, 2.0, 2, ACCEPTED, 2.0, 2),
                           SETTLE_S + 0.1 * k)
    metrics.add_update("imu", UpdateResult(True, 3.0, 3, ACCEPTED, 3.0, 3), 0.5)
    metrics.add_update("imu", UpdateResult(False, 30.0, 3, GATE, 30.0, 3), SETTLE_S)
    result = metrics.result(1.0, True)
    assert result["nis_gnss"] == pytest.approx((3 * 8.0 + 9 * 2.0) / 24)
    assert result["nis_settled_gnss"] == pytest.approx(1.0)
    assert result["nis_settled_dof_gnss"] == 18
    assert result["gated_first_s_gnss"] == 2
    assert result["tested_first_s_gnss"] == 3
    assert result["nis_settled_imu"] == pytest.approx(10.0)
    assert result["gated_first_s_imu"] == 0
    assert result["tested_first_s_imu"] == 1
    # Over the whole run: the start-up's two gated gnss updates of its 12, and the imu's
    # one update gated after settling, of its 2.
    assert (result["updates_gated_gnss"], result["updates_tested_gnss"]) == (2, 12)
    assert (result["updates_gated_imu"], result["updates_tested_imu"]) == (1, 2)
    assert undocumented(result) == []


def test_a_sensor_heard_only_at_start_up_has_no_settled_nis() -> None:
    metrics = _accumulator()
    metrics.add_update("steering", UpdateResult(True, 1.0, 1, ACCEPTED, 1.0, 1), 0.2)
    result = metrics.result(1.0, True)
    assert "nis_settled_steering" not in result
    assert result["gated_first_s_steering"] == 0


def test_estimation_errors_and_nees_over_many_blocks() -> None:
    # 2,500 estimates (more than two blocks), each with its own covariance over states in
    # an order of the estimator's own and a yaw across the +-pi seam: NEES e' P^-1 e and
    # the RMS errors as computed one by one; a covariance that is not positive definite
    # leaves that sample out of NEES only.
    rng = np.random.default_rng(4)
    names = ("vx_mps", "yaw_rad", "extra", "y_m", "x_m")
    metrics, nees = _accumulator(), []
    for k in range(2500):
        root = rng.normal(0.0, 1.0, (5, 5))
        covariance = root @ root.T + 0.1 * np.eye(5)
        if k == 1234:
            covariance[1, 1] = -1.0
        mean = rng.normal(0.0, 1.0, 5)
        mean[1] = np.pi - 0.01
        truth = VehicleState(0.01 * k, mean[4] + 0.3, mean[3] - 0.2, 0.0, 0.0, 0.0,
                             -np.pi + 0.02, mean[0] + 0.1, 0.0, 0.0, 0.0, 0.0, 0.0,
                             (0.0, 0.0, 0.0, 0.0))
        metrics.add_estimate(Estimate(truth.t_s, names, mean, covariance), truth)
        error = np.array([-0.3, 0.2, -0.03, -0.1])
        block = covariance[np.ix_([4, 3, 1, 0], [4, 3, 1, 0])]
        if k != 1234:
            nees.append(error @ np.linalg.solve(block, error))
    stats = metrics.statistics()
    assert stats["nees"].count == 2499
    assert stats["nees"].mean == pytest.approx(np.mean(nees), rel=1e-12)
    assert stats["yaw_err_rad"].rms == pytest.approx(0.03, rel=1e-9)
    assert stats["pos_err_m"].rms == pytest.approx(np.hypot(0.3, 0.2), rel=1e-12)
    assert stats["speed_est_err_mps"].mean == pytest.approx(-0.1, rel=1e-12)
    assert metrics.result(1.0, True)["nees_mean"] == stats["nees"].mean
