"""The EKF's contract: time handling, rejection and counting, gating, angles, copies."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosim.config_fields import from_dict
from cosim.exceptions import ConfigError
from cosim.initial_state import InitialState
from cosim.records import Measurement
from cosim.vehicle_params import VehicleParams
from estimation.config import EstimatorConfig
from estimation.ekf import Ekf
from estimation.errors import TimeOrderError
from estimation.models import STATE_NAMES
from estimation.update_result import REASONS

IMU_NAMES = ("yaw_rate_radps", "ax_mps2", "ay_mps2")
IMU_COV = np.diag([0.003, 0.05, 0.05]) ** 2
GNSS_COV = np.eye(2) * 0.02**2


def _ekf(config: EstimatorConfig | None = None, **initial: float) -> Ekf:
    return Ekf(config or EstimatorConfig(), InitialState(**initial), VehicleParams())


def _gnss(t_s: float, x_m: float, y_m: float, cov: np.ndarray = GNSS_COV) -> Measurement:
    return Measurement("gnss", t_s, ("x_m", "y_m"), np.array([x_m, y_m]), cov)


def _imu(t_s: float, yaw_rate: float, ax: float = 0.0, ay: float = 0.0) -> Measurement:
    return Measurement("imu", t_s, IMU_NAMES, np.array([yaw_rate, ax, ay]), IMU_COV)


def test_initial_estimate_comes_from_the_initial_state() -> None:
    config = EstimatorConfig()
    ekf = _ekf(config, x_m=5.0, y_m=-3.0, yaw_rad=1.0, speed_mps=12.0)
    estimate = ekf.estimate()
    assert estimate.t_s == 0.0
    assert estimate.names == STATE_NAMES
    expected = {
        "x_m": 5.0,
        "y_m": -3.0,
        "yaw_rad": 1.0,
        "vx_mps": 12.0,
        "rolling_radius_scale": 1.0,
    }
    for name in STATE_NAMES:
        assert estimate[name] == pytest.approx(expected.get(name, 0.0))
    sigma = np.sqrt(np.diag(estimate.covariance))
    assert sigma[STATE_NAMES.index("x_m")] == pytest.approx(config.init_position_sigma_m)
    assert sigma[STATE_NAMES.index("yaw_rad")] == pytest.approx(config.init_yaw_sigma_rad)
    assert sigma[STATE_NAMES.index("ax_mps2")] == pytest.approx(config.init_accel_sigma_mps2)


def test_estimate_is_a_copy() -> None:
    ekf = _ekf()
    estimate = ekf.estimate()
    estimate.mean[:] = 99.0
    estimate.covariance[:] = 99.0
    assert ekf.estimate()["x_m"] == 0.0
    assert ekf.estimate().covariance[0, 1] == 0.0


def test_predict_at_the_current_time_is_a_no_op() -> None:
    ekf = _ekf()
    ekf.predict(0.5)
    before = ekf.estimate()
    ekf.predict(0.5)
    after = ekf.estimate()
    assert after.t_s == before.t_s
    np.testing.assert_array_equal(after.mean, before.mean)
    np.testing.assert_array_equal(after.covariance, before.covariance)


def test_predict_refuses_to_go_back_in_time() -> None:
    ekf = _ekf()
    ekf.predict(1.0)
    with pytest.raises(TimeOrderError, match="cannot go back"):
        ekf.predict(0.99)
    with pytest.raises(ValueError, match="finite"):
        ekf.predict(math.nan)
    assert ekf.t_s == 1.0


def test_prediction_does_not_depend_on_how_the_interval_is_split() -> None:
    """One predict over 1 s or ~70 irregular ones: same mean, same covariance."""
    config = EstimatorConfig(gate=False)
    one, many = _ekf(config, speed_mps=15.0), _ekf(config, speed_mps=15.0)
    for ekf in (one, many):  # start turning and accelerating
        assert ekf.update(_imu(0.0, yaw_rate=0.3, ax=1.0, ay=4.5)).accepted
    one.predict(1.0)
    rng = np.random.default_rng(3)
    t_s = 0.0
    while t_s < 1.0:
        t_s = min(1.0, t_s + rng.uniform(0.0005, 0.03))
        many.predict(t_s)
    a, b = one.estimate(), many.estimate()
    assert b.t_s == a.t_s == 1.0
    np.testing.assert_allclose(b.mean, a.mean, rtol=1e-9, atol=1e-9)
    # Compared on the scale of the standard deviations (correlation-like units): the
    # Jacobians are taken at different points, so only nearly equal.
    scale = np.sqrt(np.outer(np.diag(a.covariance), np.diag(a.covariance)))
    np.testing.assert_allclose(b.covariance / scale, a.covariance / scale, rtol=0, atol=1e-5)


def test_measurement_in_the_future_is_predicted_to() -> None:
    ekf = _ekf(speed_mps=20.0)
    result = ekf.update(_gnss(2.0, 40.0, 0.0))
    assert result.accepted and result.dim == 2
    assert ekf.t_s == 2.0
    assert ekf.estimate()["x_m"] == pytest.approx(40.0, abs=0.01)


def test_non_finite_measurements_are_rejected_and_counted() -> None:
    ekf = _ekf(speed_mps=10.0)
    assert ekf.update(_gnss(0.1, 1.0, 0.0)).accepted
    before = ekf.estimate()
    bad = [
        _gnss(0.2, math.nan, 0.0),
        _gnss(0.2, 2.0, math.inf),
        _gnss(0.2, 2.0, 0.0, cov=np.array([[math.nan, 0.0], [0.0, 1.0]])),
        _gnss(math.nan, 2.0, 0.0),
    ]
    for measurement in bad:
        result = ekf.update(measurement)
        assert not result.accepted
        assert result.reason == "non-finite"
        assert math.isnan(result.nis)
    after = ekf.estimate()
    assert np.isfinite(after.mean).all() and np.isfinite(after.covariance).all()
    np.testing.assert_array_equal(after.mean, before.mean)
    assert after.t_s == before.t_s  # a rejected measurement does not even move the time
    assert ekf.counts()["gnss"]["rejected_nonfinite"] == 4
    assert ekf.counts()["gnss"]["accepted"] == 1


def test_stale_measurements_are_rejected_and_counted() -> None:
    ekf = _ekf(speed_mps=10.0)
    ekf.predict(1.0)
    result = ekf.update(_gnss(0.5, 5.0, 0.0))
    assert not result.accepted and result.reason == "stale"
    assert ekf.counts()["gnss"]["rejected_stale"] == 1


def test_unmodelled_sensors_are_ignored_not_rejected() -> None:
    ekf = _ekf()
    truth = Measurement("truth", 0.1, ("x_m",), np.array([1.0]), np.zeros((1, 1)))
    result = ekf.update(truth)
    assert not result.accepted and result.dim == 0 and result.reason == "ignored"
    counts = ekf.counts()["truth"]
    assert counts["ignored"] == 1
    assert sum(v for k, v in counts.items() if k.startswith("rejected")) == 0
    assert ekf.t_s == 0.0


def test_unknown_channel_and_bad_shapes_raise() -> None:
    ekf = _ekf()
    with pytest.raises(ValueError, match="z_m"):
        ekf.update(Measurement("gnss", 0.1, ("x_m", "z_m"), np.zeros(2), np.eye(2)))
    with pytest.raises(ValueError, match="shape"):
        ekf.update(Measurement("gnss", 0.1, ("x_m", "y_m"), np.zeros(3), np.eye(2)))


def test_front_wheels_are_ignored_rear_wheels_fused() -> None:
    belief = VehicleParams()
    ekf = Ekf(EstimatorConfig(), InitialState(speed_mps=10.0), belief)
    names = ("front_left_radps", "front_right_radps", "rear_left_radps", "rear_right_radps")
    spin = 11.0 / belief.wheel_radius_m
    values = np.array([-1e3, 1e3, spin, spin])  # front channels are nonsense on purpose
    result = ekf.update(Measurement("wheel_speed", 0.01, names, values, np.eye(4) * 0.01))
    assert result.accepted and result.dim == 2
    assert 10.0 < ekf.estimate()["vx_mps"] <= 11.0


def test_outlier_is_gated_and_counted_and_gate_off_accepts_it() -> None:
    gated, open_gate = _ekf(speed_mps=10.0), _ekf(EstimatorConfig(gate=False), speed_mps=10.0)
    for ekf in (gated, open_gate):
        for k in range(1, 31):
            assert ekf.update(_gnss(0.1 * k, 1.0 * k, 0.0)).accepted
    outlier = _gnss(3.1, 31.0 + 20.0, 20.0)
    result = gated.update(outlier)
    assert not result.accepted and result.reason == "gate"
    assert result.nis > gated.gate_threshold(2)
    assert gated.counts()["gnss"]["rejected_gate"] == 1
    assert gated.counts()["gnss"]["channels_gated"] == 2
    assert gated.estimate()["x_m"] == pytest.approx(31.0, abs=0.1)
    assert gated.estimate()["y_m"] == pytest.approx(0.0, abs=0.1)
    result = open_gate.update(outlier)
    assert result.accepted and result.nis > 1e3
    assert open_gate.estimate()["x_m"] > 40.0


def test_channels_are_gated_one_by_one() -> None:
    """A jump in x alone costs the x channel only; y is still fused."""
    ekf = _ekf(speed_mps=10.0)
    for k in range(1, 31):
        assert ekf.update(_gnss(0.1 * k, 1.0 * k, 0.0)).accepted
    ekf.predict(3.1)
    y_sigma_before = math.sqrt(ekf.estimate().sub_covariance(("y_m",))[0, 0])
    result = ekf.update(_gnss(3.1, 31.0 + 20.0, 0.01))
    assert result.accepted and result.reason == "partial" and result.dim == 1
    counts = ekf.counts()["gnss"]
    assert counts["channels_gated"] == 1 and counts["rejected_gate"] == 0
    estimate = ekf.estimate()
    assert estimate["x_m"] == pytest.approx(31.0, abs=0.1)
    assert math.sqrt(estimate.sub_covariance(("y_m",))[0, 0]) < y_sigma_before


def test_spinning_wheel_is_gated_alone() -> None:
    """The inside rear wheel spins up by 10 %: its channel is gated, the other one fused."""
    belief = VehicleParams()
    ekf = Ekf(EstimatorConfig(), InitialState(speed_mps=15.0), belief)
    names = ("rear_left_radps", "rear_right_radps")
    spin = 15.0 / belief.wheel_radius_m
    cov = np.eye(2) * 0.05**2
    for k in range(1, 51):
        measurement = Measurement("wheel_speed", 0.01 * k, names, np.array([spin, spin]), cov)
        assert ekf.update(measurement).reason == "accepted"
    slipping = Measurement("wheel_speed", 0.51, names, np.array([spin, 1.1 * spin]), cov)
    result = ekf.update(slipping)
    assert result.reason == "partial" and result.dim == 1
    assert ekf.estimate()["vx_mps"] == pytest.approx(15.0, abs=0.05)


def test_gate_threshold_is_the_chi_square_quantile() -> None:
    ekf = _ekf(EstimatorConfig(gate_probability=0.99))
    assert ekf.gate_threshold(1) == pytest.approx(6.634897, rel=1e-6)
    assert ekf.gate_threshold(2) == pytest.approx(9.210340, rel=1e-6)
    with pytest.raises(ValueError):
        ekf.gate_threshold(0)


def test_gate_is_released_after_persistent_rejections() -> None:
    """A lasting jump of the GNSS is believed after gate_release_s of rejections."""
    ekf = _ekf(EstimatorConfig(gate_release_s=1.0), speed_mps=10.0)
    for k in range(1, 31):
        ekf.update(_gnss(0.1 * k, 1.0 * k, 0.0))
    reasons = []
    for k in range(31, 80):
        reasons.append(ekf.update(_gnss(0.1 * k, 1.0 * k + 20.0, 20.0)).reason)
    counts = ekf.counts()["gnss"]
    assert counts["rejected_gate"] == 10  # 3.1 s .. 4.0 s
    assert counts["gate_released"] == 2  # the x and the y channel, once each
    assert reasons[:10] == ["gate"] * 10
    assert reasons[10] == "gate-released"
    # The jump is taken as a jump of the position, not of the speed: no oscillation after.
    assert reasons[11:] == ["accepted"] * (len(reasons) - 11)
    estimate = ekf.estimate()
    assert estimate["x_m"] == pytest.approx(7.9 * 10.0 + 20.0, abs=0.01)
    assert estimate["y_m"] == pytest.approx(20.0, abs=0.01)
    assert estimate["vx_mps"] == pytest.approx(10.0, abs=0.01)


def test_yaw_is_wrapped_through_pi() -> None:
    ekf = _ekf(yaw_rad=3.0, speed_mps=10.0)
    for k in range(1, 101):
        ekf.update(_imu(0.01 * k, yaw_rate=0.5, ay=5.0))
    yaw = ekf.estimate()["yaw_rad"]
    assert -math.pi < yaw <= math.pi
    assert yaw == pytest.approx(3.0 + 0.5 - 2 * math.pi, abs=0.02)


def test_angle_innovation_is_wrapped() -> None:
    """A heading of -3.1 rad seen from 3.1 rad is 0.083 rad away, not 6.2 rad."""
    ekf = _ekf(yaw_rad=3.1)
    heading = Measurement("heading", 0.0, ("yaw_rad",), np.array([-3.1]), np.eye(1) * 0.05**2)
    result = ekf.update(heading)
    assert result.accepted
    expected_innovation = 2 * math.pi - 6.2
    assert result.nis == pytest.approx(expected_innovation**2 / (2 * 0.05**2), rel=1e-6)
    yaw = ekf.estimate()["yaw_rad"]
    assert abs(yaw) > 3.1  # moved towards pi, across it or not
    assert -math.pi < yaw <= math.pi


def test_covariance_stays_symmetric_positive_definite() -> None:
    ekf = _ekf(speed_mps=15.0)
    rng = np.random.default_rng(0)
    for k in range(1, 501):
        t_s = 0.01 * k
        ekf.update(_imu(t_s, 0.1 + rng.normal(0, 0.003), rng.normal(0, 0.05), 1.5))
        if k % 10 == 0:
            ekf.update(_gnss(t_s, 15.0 * t_s, 0.0, cov=np.eye(2) * 1e-6))
    covariance = ekf.estimate().covariance
    np.testing.assert_array_equal(covariance, covariance.T)
    assert np.linalg.eigvalsh(covariance).min() > 0.0


def test_config_from_dict_and_validation() -> None:
    config = from_dict(EstimatorConfig, {"gate": False, "jerk_psd_m2ps5": 10}, "estimator")
    assert config.gate is False and config.jerk_psd_m2ps5 == 10.0
    with pytest.raises(ConfigError, match="estimator.name"):
        from_dict(EstimatorConfig, {"name": "ukf"}, "estimator")
    with pytest.raises(ConfigError, match="estimator.gate_probability"):
        from_dict(EstimatorConfig, {"gate_probability": 1.5}, "estimator")
    with pytest.raises(ConfigError, match="estimator.gate"):
        from_dict(EstimatorConfig, {"gate": "no"}, "estimator")
    with pytest.raises(ConfigError, match="estimator.max_step_s"):
        _ekf(EstimatorConfig(max_step_s=0.05))  # built directly, bypassing from_dict


def test_reasons_are_exact_codes() -> None:
    """Callers compare reasons as strings (the runner counts ``reason != "ignored"``)."""
    assert REASONS == (
        "accepted",
        "partial",
        "gate-released",
        "gate",
        "non-finite",
        "stale",
        "invalid",
        "ignored",
    )
