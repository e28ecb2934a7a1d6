"""Sensor faults in the closed loop: the real plant, sensors, tracker and runner, both filters.

Each fault of the issue's list is injected as data (``faults:``, cosim/sensing/faults.py) into the
lane change with the default (RTK) suite, shortened to 11 s (every fault and its recovery
lie inside). The figures come from the run's log (truth and estimate at 100 Hz) and
metrics; each faulty run is compared with the same seed's run without the fault.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

from cosim.log.reader import iter_messages
from cosim.simulation.runner import RunResult, run
from cosim.simulation.scenario_config import load_config

pytestmark = pytest.mark.slow

DURATION_S = 11.0
FAULTS = {
    "none": "[]",
    # The receiver falls silent: its fixes and its Doppler velocity (the rtk suite has both).
    "dropout": "[{kind: dropout, sensor: gnss, start_s: 5, end_s: 8},"
               " {kind: dropout, sensor: gnss_velocity, start_s: 5, end_s: 8}]",
    "outlier": "[{kind: outlier, sensor: gnss, start_s: 9, offset: 20}]",
    "nan": "[{kind: nan, sensor: imu, start_s: 6, end_s: 7}]",
}


@pytest.fixture(scope="module", params=("ekf", "ukf"))
def runs(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
         ) -> dict[str, RunResult]:
    """One run per fault (and one without) of the filter ``request.param``."""
    out = tmp_path_factory.mktemp(f"faults-{request.param}")
    results = {}
    for fault, value in FAULTS.items():
        config = load_config("lane-change", overrides=[f"faults={value}"], seed=0,
                             duration_s=DURATION_S, estimator=request.param)
        results[fault] = run(config, out / f"{fault}.mcap")
        assert results[fault].completed
    return results


def _position_error(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times, |estimated - true position| and the estimate's x standard deviation."""
    truth = [m for _, m in iter_messages(path, "/vehicle/truth")]
    estimate = [m for _, m in iter_messages(path, "/vehicle/estimate")]
    t_s = np.array([m["t_s"] for m in truth])
    np.testing.assert_allclose([m["t_s"] for m in estimate], t_s, rtol=0, atol=1e-9)
    error = np.hypot(
        np.array([e["x_m"] - m["x_m"] for e, m in zip(estimate, truth, strict=True)]),
        np.array([e["y_m"] - m["y_m"] for e, m in zip(estimate, truth, strict=True)]),
    )
    names = estimate[0]["state_names"]
    x = names.index("x_m")
    sigma_x = np.array([np.sqrt(e["covariance"][x * len(names) + x]) for e in estimate])
    return t_s, error, sigma_x


def _no_constant(token: str) -> float:
    raise ValueError(f"non-finite number {token} in a logged message")


def test_gnss_dropout_keeps_the_error_below_1_m_and_recovers_within_2_s(
    runs: dict[str, RunResult],
) -> None:
    """GNSS silent 5-8 s, in the middle of the lane change: 30 fixes and their 30 Doppler
    velocities dropped, the position error stays below 1 m, and from 10 s (2 s after the
    fixes return) the error and the uncertainty are back where they were before the
    outage."""
    result = runs["dropout"]
    assert result.metrics["faults_injected"] == 60
    t_s, error, sigma = _position_error(result.log_path)
    before = (t_s >= 3.0) & (t_s < 5.0)
    outage = (t_s >= 5.0) & (t_s < 8.0)
    recovered = t_s >= 10.0
    print(f"dropout: max error before {error[before].max():.3f} m, during "
          f"{error[outage].max():.3f} m, from 10 s {error[recovered].max():.3f} m")
    assert error[outage].max() < 1.0
    assert sigma[outage].max() > 3.0 * sigma[before].max()  # it knows it is blind
    assert sigma[recovered].max() < 1.5 * sigma[before].max()
    assert error[recovered].max() < max(2.0 * error[before].max(), 0.1)


def test_gnss_outlier_is_rejected_counted_and_moves_the_estimate_less_than_20_cm(
    runs: dict[str, RunResult],
) -> None:
    """One fix 20 m east at 9 s: its east channel is gated (counted in channels_gated; the
    north channel agrees and is fused), and the estimate moves by less than 0.2 m from the
    fault-free run's."""
    faulty, clean = runs["outlier"], runs["none"]
    assert faulty.metrics["faults_injected"] == 1
    gated = (faulty.metrics["rejected_measurements"] + faulty.metrics["channels_gated"]
             - clean.metrics["rejected_measurements"] - clean.metrics["channels_gated"])
    assert gated >= 1
    t_s, error, _ = _position_error(faulty.log_path)
    _, clean_error, _ = _position_error(clean.log_path)
    after = t_s >= 9.0
    estimates = [np.array([m["x_m"], m["y_m"]])
                 for _, m in iter_messages(faulty.log_path, "/vehicle/estimate")]
    clean_estimates = [np.array([m["x_m"], m["y_m"]])
                       for _, m in iter_messages(clean.log_path, "/vehicle/estimate")]
    moved = np.array([np.hypot(*(a - b)) for a, b in zip(estimates, clean_estimates,
                                                           strict=True)])
    print(f"outlier: estimate moved by at most {moved.max():.4f} m; error after 9 s "
          f"{error[after].max():.3f} m (without the fault {clean_error[after].max():.3f} m)")
    assert moved.max() < 0.2
    assert error[after].max() < 0.2


def test_imu_nan_is_rejected_counted_and_never_reaches_the_estimate_or_the_log(
    runs: dict[str, RunResult],
) -> None:
    """NaN IMU samples for 1 s (100 at 100 Hz): all rejected as non-finite and counted; the
    estimate, every logged message and the metrics stay finite (the faulty samples are
    logged as null, JSON's "no value")."""
    result = runs["nan"]
    assert result.metrics["faults_injected"] == 100
    assert result.metrics["rejected_nonfinite"] == 100
    assert result.metrics["rejected_measurements"] >= 100
    with open(result.log_path, "rb") as stream:
        for _, channel, message in make_reader(stream).iter_messages():
            decoded = json.loads(message.data, parse_constant=_no_constant)
            if channel.topic == "/vehicle/estimate":
                values = [v for k, v in decoded.items() if k != "state_names"]
                flat = [x for v in values for x in (v if isinstance(v, list) else [v])]
                assert all(isinstance(x, int | float) for x in flat), decoded["t_s"]
    nulls = [m for _, m in iter_messages(result.log_path, "/sensors/imu")
             if m["yaw_rate_radps"] is None]
    assert len(nulls) == 100
    t_s, error, _ = _position_error(result.log_path)
    assert error[t_s >= 5.0].max() < 0.2
    assert all(np.isfinite(v) for v in result.metrics.values() if isinstance(v, float)
               and not isinstance(v, bool))
