"""The filters' contract (EKF and UKF alike): time handling, rejection and counting, gating,
angles, copies, a positive definite covariance."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from cosim.core.config_fields import from_dict
from cosim.core.exceptions import ConfigError
from cosim.core.initial_state import InitialState
from cosim.core.records import Measurement
from cosim.core.vehicle_params import VehicleParams
from estimation.config import EstimatorConfig
from estimation.errors import TimeOrderError
from estimation.fusion import KalmanFusion
from estimation.noise_config import NoiseBelief
from estimation.registry import make_estimator
from estimation.state import STATE_NAMES
from estimation.update_result import REASONS

FILTERS = ("ekf", "ukf")

IMU_NAMES = ("yaw_rate_radps", "ax_mps2", "ay_mps2")
IMU_COV = np.diag([0.003, 0.05, 0.05]) ** 2
WHEEL_NAMES = ("front_left_radps", "front_right_radps", "rear_left_radps", "rear_right_radps")
GNSS_COV = np.eye(2) * 0.02**2


@pytest.fixture(params=FILTERS)
def name(request: pytest.FixtureRequest) -> str:
    """Every test taking ``name`` runs for each filter."""
    return request.param


def _filter(name: str, config: EstimatorConfig | None = None, **initial: float) -> KalmanFusion:
    config = dataclasses.replace(config or EstimatorConfig(), name=name)
    estimator = make_estimator(config, InitialState(**initial), VehicleParams())
    assert isinstance(estimator, KalmanFusion)
    return estimator


def _gnss(t_s: float, x_m: float, y_m: float, cov: np.ndarray = GNSS_COV) -> Measurement:
    return Measurement("gnss", t_s, ("x_m", "y_m"), np.array([x_m, y_m]), cov)


def _imu(t_s: float, yaw_rate: float, ax: float = 0.0, ay: float = 0.0) -> Measurement:
    return Measurement("imu", t_s, IMU_NAMES, np.array([yaw_rate, ax, ay]), IMU_COV)


def test_initial_estimate_comes_from_the_initial_state(name: str) -> None:
    config = EstimatorConfig()
    kf = _filter(name, config, x_m=5.0, y_m=-3.0, yaw_rad=1.0, speed_mps=12.0)
    estimate = kf.estimate()
    assert estimate.t_s == 0.0
    assert estimate.names == STATE_NAMES
    expected = {
        "x_m": 5.0,
        "y_m": -3.0,
        "yaw_rad": 1.0,
        "vx_mps": 12.0,
        "rolling_radius_scale": 1.0,
        "wheel_track_scale": 1.0,
    }
    for name in STATE_NAMES:
        assert estimate[name] == pytest.approx(expected.get(name, 0.0))
    sigma = np.sqrt(np.diag(estimate.covariance))
    assert sigma[STATE_NAMES.index("x_m")] == pytest.approx(config.init_position_sigma_m)
    assert sigma[STATE_NAMES.index("yaw_rad")] == pytest.approx(config.init_yaw_sigma_rad)
    assert sigma[STATE_NAMES.index("ax_mps2")] == pytest.approx(config.init_accel_sigma_mps2)


def test_measurement_noise_is_the_filters_belief_not_the_sensors(name: str) -> None:
    """R comes from ``estimator.noise``: the covariance a measurement carries (the sensor's
    truth, which a real filter cannot know) changes nothing; the belief does."""
    results = []
    for carried, believed in ((1e-4, 0.02), (100.0, 0.02), (1e-4, 0.5)):
        config = EstimatorConfig(noise=NoiseBelief(gnss_sigma_m=believed))
        kf = _filter(name, config, speed_mps=10.0)
        result = kf.update(_gnss(0.0, 1.0, 0.0, cov=np.eye(2) * carried))
        results.append((result.nis, kf.estimate()["x_m"]))
    assert results[0] == results[1]
    p0 = EstimatorConfig().init_position_sigma_m**2
    assert results[0][0] == pytest.approx(1.0 / (p0 + 0.02**2), rel=1e-6)
    assert results[2][0] == pytest.approx(1.0 / (p0 + 0.5**2), rel=1e-6)
    assert results[2][1] < results[0][1]


def test_initial_estimate_is_drawn_around_the_truth(name: str) -> None:
    """``sampled``: the prior mean is the truth plus a draw from N(0, P0) (the same for the
    same generator); ``truth``: the truth itself; ``first-fix``: sampled, then the position
    is the first GNSS fix with the believed GNSS covariance."""
    initial = {"x_m": 5.0, "y_m": -3.0, "yaw_rad": 1.0, "speed_mps": 12.0}
    means = []
    for mode in ("sampled", "sampled", "truth"):
        config = dataclasses.replace(EstimatorConfig(initial=mode), name=name)
        kf = make_estimator(config, InitialState(**initial), VehicleParams(),
                            rng=np.random.default_rng(4))
        means.append(kf.estimate().mean)
    np.testing.assert_array_equal(means[0], means[1])
    assert means[2][STATE_NAMES.index("x_m")] == 5.0
    config = EstimatorConfig()
    errors = (means[0] - means[2]) / np.sqrt(np.diag(
        make_estimator(config, InitialState(**initial), VehicleParams()).estimate().covariance))
    moved = {n for n, e in zip(STATE_NAMES, errors, strict=True) if e != 0.0}
    assert {"x_m", "y_m", "yaw_rad", "vx_mps", "steer_rad"} <= moved
    assert "rolling_radius_scale" not in moved and "gyro_bias_radps" not in moved
    assert np.all(np.abs(errors) < 5.0)

    config = dataclasses.replace(EstimatorConfig(initial="first-fix"), name=name)
    kf = make_estimator(config, InitialState(**initial), VehicleParams(),
                        rng=np.random.default_rng(4))
    result = kf.update(_gnss(0.0, 5.3, -2.9))
    assert result.accepted and math.isnan(result.nis)
    estimate = kf.estimate()
    assert (estimate["x_m"], estimate["y_m"]) == (5.3, -2.9)
    np.testing.assert_allclose(estimate.sub_covariance(("x_m", "y_m")),
                               np.eye(2) * config.noise.gnss_sigma_m**2)
    assert kf.update(_gnss(0.1, 6.5, -2.9)).joint_dim == 2  # later fixes are updates


def test_estimate_is_a_copy(name: str) -> None:
    kf = _filter(name)
    estimate = kf.estimate()
    estimate.mean[:] = 99.0
    estimate.covariance[:] = 99.0
    assert kf.estimate()["x_m"] == 0.0
    assert kf.estimate().covariance[0, 1] == 0.0


def test_predict_at_the_current_time_is_a_no_op(name: str) -> None:
    kf = _filter(name)
    kf.predict(0.5)
    before = kf.estimate()
    kf.predict(0.5)
    after = kf.estimate()
    assert after.t_s == before.t_s
    np.testing.assert_array_equal(after.mean, before.mean)
    np.testing.assert_array_equal(after.covariance, before.covariance)


def test_predict_refuses_to_go_back_in_time(name: str) -> None:
    kf = _filter(name)
    kf.predict(1.0)
    with pytest.raises(TimeOrderError, match="cannot go back"):
        kf.predict(0.99)
    with pytest.raises(ValueError, match="finite"):
        kf.predict(math.nan)
    assert kf.t_s == 1.0


def test_prediction_does_not_depend_on_how_the_interval_is_split(name: str) -> None:
    """One predict over 1 s or ~70 irregular ones: same mean, same covariance.

    The EKF's mean is the RK4 solution either way (to its truncation error, a millionth of
    a standard deviation); the UKF's mean is an average over sigma points drawn afresh at
    every sub-step, so it agrees to a small fraction of a standard deviation, and its
    covariance, where the sigma points reach into the saturating tyres (the steering angle is
    unmeasured here and its spread grows), to 15 %.
    """
    config = EstimatorConfig(gate=False)
    one, many = _filter(name, config, speed_mps=15.0), _filter(name, config, speed_mps=15.0)
    for kf in (one, many):  # start turning and accelerating
        assert kf.update(_imu(0.0, yaw_rate=0.3, ax=1.0, ay=4.5)).accepted
    one.predict(1.0)
    rng = np.random.default_rng(3)
    t_s = 0.0
    while t_s < 1.0:
        t_s = min(1.0, t_s + rng.uniform(0.0005, 0.03))
        many.predict(t_s)
    a, b = one.estimate(), many.estimate()
    assert b.t_s == a.t_s == 1.0
    sigma = np.sqrt(np.diag(a.covariance))
    mean_tolerance = 1e-6 if name == "ekf" else 1e-3
    np.testing.assert_allclose(b.mean / sigma, a.mean / sigma, rtol=0, atol=mean_tolerance)
    # Compared on the scale of the standard deviations (correlation-like units): the
    # Jacobians and the force-dependent noise PSDs are taken at each sub-step's start, so
    # only nearly equal.
    scale = np.sqrt(np.outer(np.diag(a.covariance), np.diag(a.covariance)))
    tolerance = 1e-3 if name == "ekf" else 0.15
    np.testing.assert_allclose(b.covariance / scale, a.covariance / scale, rtol=0, atol=tolerance)


def test_measurement_in_the_future_is_predicted_to(name: str) -> None:
    kf = _filter(name, speed_mps=20.0)
    result = kf.update(_gnss(2.0, 40.0, 0.0))
    assert result.accepted and result.dim == 2
    assert kf.t_s == 2.0
    assert kf.estimate()["x_m"] == pytest.approx(40.0, abs=0.01)


def test_non_finite_measurements_are_rejected_and_counted(name: str) -> None:
    kf = _filter(name, speed_mps=10.0)
    assert kf.update(_gnss(0.1, 1.0, 0.0)).accepted
    before = kf.estimate()
    bad = [
        _gnss(0.2, math.nan, 0.0),
        _gnss(0.2, 2.0, math.inf),
        _gnss(0.2, math.nan, math.nan),
        _gnss(math.nan, 2.0, 0.0),
    ]
    for measurement in bad:
        result = kf.update(measurement)
        assert not result.accepted
        assert result.reason == "non-finite"
        assert math.isnan(result.nis)
    after = kf.estimate()
    assert np.isfinite(after.mean).all() and np.isfinite(after.covariance).all()
    np.testing.assert_array_equal(after.mean, before.mean)
    assert after.t_s == before.t_s  # a rejected measurement does not even move the time
    assert kf.counts()["gnss"]["rejected_nonfinite"] == 4
    assert kf.counts()["gnss"]["accepted"] == 1


def test_stale_measurements_are_rejected_and_counted(name: str) -> None:
    kf = _filter(name, speed_mps=10.0)
    kf.predict(1.0)
    result = kf.update(_gnss(0.5, 5.0, 0.0))
    assert not result.accepted and result.reason == "stale"
    assert kf.counts()["gnss"]["rejected_stale"] == 1


def test_unmodelled_sensors_are_ignored_not_rejected(name: str) -> None:
    kf = _filter(name)
    truth = Measurement("truth", 0.1, ("x_m",), np.array([1.0]), np.zeros((1, 1)))
    result = kf.update(truth)
    assert not result.accepted and result.dim == 0 and result.reason == "ignored"
    counts = kf.counts()["truth"]
    assert counts["ignored"] == 1
    assert sum(v for k, v in counts.items() if k.startswith("rejected")) == 0
    assert kf.t_s == 0.0


def test_unknown_channel_and_bad_shapes_raise(name: str) -> None:
    kf = _filter(name)
    with pytest.raises(ValueError, match="z_m"):
        kf.update(Measurement("gnss", 0.1, ("x_m", "z_m"), np.zeros(2), np.eye(2)))
    with pytest.raises(ValueError, match="shape"):
        kf.update(Measurement("gnss", 0.1, ("x_m", "y_m"), np.zeros(3), np.eye(2)))


def test_driven_wheels_are_ignored_free_wheels_fused(name: str) -> None:
    """The sedan is rear-wheel driven: its front wheels tell the speed, the rear ones slip."""
    radius = VehicleParams().wheel_radius_m
    kf = _filter(name, speed_mps=10.0)
    spin = 11.0 / radius
    values = np.array([spin, spin, -1e3, 1e3])  # rear channels are nonsense on purpose
    result = kf.update(Measurement("wheel_speed", 0.01, WHEEL_NAMES, values, np.eye(4) * 0.01))
    assert result.accepted and result.dim == 2
    assert 10.0 < kf.estimate()["vx_mps"] <= 11.0


def test_outlier_is_gated_and_counted_and_gate_off_accepts_it(name: str) -> None:
    gated = _filter(name, speed_mps=10.0)
    open_gate = _filter(name, EstimatorConfig(gate=False), speed_mps=10.0)
    for kf in (gated, open_gate):
        for k in range(1, 31):
            assert kf.update(_gnss(0.1 * k, 1.0 * k, 0.0)).accepted
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
    assert open_gate.estimate()["x_m"] > 31.0 + 0.25 * 20.0  # pulled a good part of the jump


def test_channels_are_gated_one_by_one(name: str) -> None:
    """A jump in x alone costs the x channel only; y is still fused."""
    kf = _filter(name, speed_mps=10.0)
    for k in range(1, 31):
        assert kf.update(_gnss(0.1 * k, 1.0 * k, 0.0)).accepted
    kf.predict(3.1)
    y_sigma_before = math.sqrt(kf.estimate().sub_covariance(("y_m",))[0, 0])
    result = kf.update(_gnss(3.1, 31.0 + 20.0, 0.01))
    assert result.accepted and result.reason == "partial" and result.dim == 1
    counts = kf.counts()["gnss"]
    assert counts["channels_gated"] == 1 and counts["rejected_gate"] == 0
    estimate = kf.estimate()
    assert estimate["x_m"] == pytest.approx(31.0, abs=0.1)
    assert math.sqrt(estimate.sub_covariance(("y_m",))[0, 0]) < y_sigma_before


def test_locking_wheel_is_gated_alone(name: str) -> None:
    """The right front wheel jumps by 10 % (a brake locking it, a bad tooth): its channel is
    gated, the other one fused."""
    kf = _filter(name, speed_mps=15.0)
    names = ("front_left_radps", "front_right_radps")
    spin = 15.0 / VehicleParams().wheel_radius_m
    cov = np.eye(2) * 0.05**2
    for k in range(1, 51):
        measurement = Measurement("wheel_speed", 0.01 * k, names, np.array([spin, spin]), cov)
        assert kf.update(measurement).reason == "accepted"
    slipping = Measurement("wheel_speed", 0.51, names, np.array([spin, 0.9 * spin]), cov)
    result = kf.update(slipping)
    assert result.reason == "partial" and result.dim == 1
    assert kf.estimate()["vx_mps"] == pytest.approx(15.0, abs=0.05)


def test_gate_threshold_is_the_chi_square_quantile(name: str) -> None:
    kf = _filter(name, EstimatorConfig(gate_probability=0.99))
    assert kf.gate_threshold(1) == pytest.approx(6.634897, rel=1e-6)
    assert kf.gate_threshold(2) == pytest.approx(9.210340, rel=1e-6)
    with pytest.raises(ValueError):
        kf.gate_threshold(0)


def test_gate_is_released_after_persistent_rejections(name: str) -> None:
    """A lasting jump of the GNSS is believed after gate_release_s of rejections."""
    kf = _filter(name, EstimatorConfig(gate_release_s=1.0), speed_mps=10.0)
    for k in range(1, 31):
        kf.update(_gnss(0.1 * k, 1.0 * k, 0.0))
    reasons = []
    for k in range(31, 80):
        reasons.append(kf.update(_gnss(0.1 * k, 1.0 * k + 20.0, 20.0)).reason)
    counts = kf.counts()["gnss"]
    assert counts["rejected_gate"] == 10  # 3.1 s .. 4.0 s
    assert counts["gate_released"] == 2  # the x and the y channel, once each
    assert reasons[:10] == ["gate"] * 10
    assert reasons[10] == "gate-released"
    # The jump is taken as a jump of the position, not of the speed: no oscillation after.
    assert reasons[11:] == ["accepted"] * (len(reasons) - 11)
    estimate = kf.estimate()
    assert estimate["x_m"] == pytest.approx(7.9 * 10.0 + 20.0, abs=0.01)
    assert estimate["y_m"] == pytest.approx(20.0, abs=0.01)
    assert estimate["vx_mps"] == pytest.approx(10.0, abs=0.01)


def test_a_yaw_kick_the_model_cannot_predict_moves_the_yaw_rate_not_the_gyro_bias(
        name: str) -> None:
    """Driving straight, the gyro suddenly reads 0.8 rad/s (a kick): far outside the gate,
    the ungated IMU is fused after room is made in the process noise's directions. The yaw
    rate follows the gyro within one sample, the gyro bias (a slow random walk) stays put;
    with the inflation off the same innovation leaks into the bias or the yaw rate lags."""

    def kicked(config: EstimatorConfig) -> tuple[dict[str, float], dict[str, int]]:
        kf = _filter(name, config, speed_mps=20.0)
        for k in range(1, 101):
            kf.update(_imu(0.01 * k, yaw_rate=0.0))
        kf.update(_imu(1.01, yaw_rate=0.8))
        estimate = kf.estimate()
        return ({n: estimate[n] for n in ("yaw_rate_radps", "gyro_bias_radps", "yaw_rad")},
                kf.counts()["imu"])

    state, counts = kicked(EstimatorConfig())
    assert counts["surprises"] == 1 and counts["accepted"] == 101
    assert state["yaw_rate_radps"] == pytest.approx(0.8, abs=0.02)
    assert abs(state["gyro_bias_radps"]) < 2e-3  # within its prior's sigma
    # The kick began within the last 10 ms step: the EKF moves the yaw by 0.004 rad; the
    # UKF's sigma points, spread over the inflated yaw rate, reach the tyres' saturation in
    # the lateral-acceleration channel and move it by 0.02-0.025 rad. Both far below a kick's
    # 0.09.
    assert 0.0 < state["yaw_rad"] < 0.03
    plain, plain_counts = kicked(EstimatorConfig(inflate_on_surprise=False))
    assert plain_counts["surprises"] == 0
    assert plain["yaw_rate_radps"] < 0.5 or abs(plain["gyro_bias_radps"]) > 0.01


def test_yaw_is_wrapped_through_pi(name: str) -> None:
    # Started in a turn it knows nothing of: a yaw-rate prior wide enough for 0.5 rad/s.
    config = EstimatorConfig(init_yaw_rate_sigma_radps=1.0)
    kf = _filter(name, config, yaw_rad=3.0, speed_mps=10.0)
    for k in range(1, 101):
        kf.update(_imu(0.01 * k, yaw_rate=0.5, ay=5.0))
    estimate = kf.estimate()
    yaw = estimate["yaw_rad"]
    assert -math.pi < yaw <= math.pi
    # 0.5 rad/s for 1 s; the yaw rate takes a few samples to settle from its prior. The
    # UKF's lateral states take 16 samples to explain a_y = 5 m/s^2 (its sigma points reach
    # the tyres' saturation), each sample a surprise whose room carries the heading 4 mrad
    # along: 0.06 rad ahead. (When a surprise's room took the whole innovation as motion,
    # the UKF's yaw was within 0.005 rad, its steering at -14.8 rad.)
    assert yaw == pytest.approx(3.0 + 0.5 - 2 * math.pi, abs=0.03 if name == "ekf" else 0.07)
    # The steady turn: v r = a_y, and the steering within the actuator's reach.
    assert estimate["yaw_rate_radps"] == pytest.approx(0.5, abs=0.01)
    assert 0.0 < estimate["steer_rad"] < 0.3


def test_angle_innovation_is_wrapped(name: str) -> None:
    """A heading of -3.1 rad seen from 3.1 rad is 0.083 rad away, not 6.2 rad."""
    config = EstimatorConfig(noise=NoiseBelief(heading_sigma_rad=0.05))
    kf = _filter(name, config, yaw_rad=3.1)
    heading = Measurement("heading", 0.0, ("yaw_rad",), np.array([-3.1]), np.eye(1) * 0.05**2)
    result = kf.update(heading)
    assert result.accepted
    expected_innovation = 2 * math.pi - 6.2
    variance = config.init_yaw_sigma_rad**2 + config.noise.heading_sigma_rad**2
    assert result.nis == pytest.approx(expected_innovation**2 / variance, rel=1e-6)
    yaw = kf.estimate()["yaw_rad"]
    assert abs(yaw) > 3.1  # moved towards pi, across it or not
    assert -math.pi < yaw <= math.pi


def test_covariance_stays_symmetric_positive_definite(name: str) -> None:
    kf = _filter(name, speed_mps=15.0)
    rng = np.random.default_rng(0)
    for k in range(1, 501):
        t_s = 0.01 * k
        kf.update(_imu(t_s, 0.1 + rng.normal(0, 0.003), rng.normal(0, 0.05), 1.5))
        if k % 10 == 0:
            kf.update(_gnss(t_s, 15.0 * t_s, 0.0, cov=np.eye(2) * 1e-6))
    covariance = kf.estimate().covariance
    np.testing.assert_array_equal(covariance, covariance.T)
    assert np.linalg.eigvalsh(covariance).min() > 0.0


def test_config_from_dict_and_validation(name: str) -> None:
    config = from_dict(EstimatorConfig, {"gate": False, "jerk_psd_m2ps5": 10}, "estimator")
    assert config.gate is False and config.jerk_psd_m2ps5 == 10.0
    assert from_dict(EstimatorConfig, {"name": name}, "estimator").name == name
    with pytest.raises(ConfigError, match="estimator.name"):
        from_dict(EstimatorConfig, {"name": "magic"}, "estimator")
    with pytest.raises(ConfigError, match="estimator.tyre_model"):
        from_dict(EstimatorConfig, {"tyre_model": "pacejka"}, "estimator")
    with pytest.raises(ConfigError, match="estimator.gate_probability"):
        from_dict(EstimatorConfig, {"gate_probability": 1.5}, "estimator")
    with pytest.raises(ConfigError, match="estimator.gate"):
        from_dict(EstimatorConfig, {"gate": "no"}, "estimator")
    with pytest.raises(ConfigError, match="estimator.max_step_s"):
        _filter(name, EstimatorConfig(max_step_s=0.05))  # built directly, bypassing from_dict


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


def _same_instant(t_s: float, yaw_rate: float) -> list[Measurement]:
    """A GNSS fix, an IMU sample and the steering angle of one instant."""
    return [_gnss(t_s, 20.0 * t_s + 0.01, 0.03), _imu(t_s, yaw_rate, 0.1, 0.2),
            Measurement("steering", t_s, ("steer_rad",), np.array([0.01]),
                        np.eye(1) * 1e-6)]


def _one_by_one(filter_: object, batch: list[Measurement]) -> list[object]:
    """``update`` of each measurement of ``batch`` in the order a filter fuses an instant one
    after another (the models linear in the state first), the results in the order given."""
    order = sorted(range(len(batch)), key=lambda i: not (
        filter_._models[batch[i].sensor].linear))  # type: ignore[attr-defined]
    results: dict[int, object] = {i: filter_.update(batch[i]) for i in order}  # type: ignore[attr-defined]
    return [results[i] for i in range(len(batch))]


def test_measurements_of_one_instant_fused_together_equal_one_after_another(
        name: str) -> None:
    # For a linearised model the joint update is the sequential one (Bar-Shalom et al.
    # 2001, 3.3.2); each measurement's NIS is its block of the innovation against the prior.
    together = _filter(name, speed_mps=20.0)
    apart = _filter(name, speed_mps=20.0)
    for step in range(1, 6):
        batch = _same_instant(0.1 * step, 0.02)
        results = together.update_many(batch)
        expected = _one_by_one(apart, batch)
        assert [r.reason for r in results] == [r.reason for r in expected] == ["accepted"] * 3
        assert [r.dim for r in results] == [2, 3, 1]
        # The first measurement's NIS is against the prior in both (the same prior at the
        # first instant; later ones differ by the linearisation points: one after another,
        # the steering is fused before the IMU, whose lateral acceleration is linearised at
        # the mean the GNSS and the steering left, 2e-3 of a NIS of 0.04); the others' are
        # against the prior only in the joint update.
        assert results[0].nis == pytest.approx(expected[0].nis, rel=1e-9 if step == 1 else 5e-3)
        assert all(math.isfinite(r.nis) and r.nis == r.joint_nis for r in results)
    # The EKF's sequential updates relinearise the IMU's lateral acceleration at the mean
    # the GNSS and the steering updated; the difference is a hair of the uncertainty.
    joint, sequential = together.estimate(), apart.estimate()
    sigma = np.sqrt(np.diag(sequential.covariance))
    assert np.all(np.abs(joint.mean - sequential.mean) <= 1e-3 * sigma)
    # Covariances in units of the standard deviations (correlation-coefficient units).
    scaled = (joint.covariance - sequential.covariance) / np.outer(sigma, sigma)
    assert np.abs(scaled).max() < 1e-3
    assert together.counts() == apart.counts()


def test_a_gated_measurement_sends_its_instant_one_by_one(name: str) -> None:
    together = _filter(name, speed_mps=20.0)
    apart = _filter(name, speed_mps=20.0)
    batch = _same_instant(0.1, 0.02)
    batch[0] = _gnss(0.1, 50.0, 30.0)  # 30 m off: gated
    results = together.update_many(batch)
    expected = _one_by_one(apart, batch)
    assert results == expected
    assert results[0].reason == "gate"
    np.testing.assert_array_equal(together.estimate().mean, apart.estimate().mean)


def test_one_after_another_the_linear_models_go_first(name: str) -> None:
    """estimation.update_order.linear_first: the steering angle and the GNSS position (their
    models linear in the state) before the IMU and the wheel speeds, each group in the order
    given; a sensor without a model counts as nonlinear."""
    from estimation.update_order import linear_first

    kf = _filter(name)
    batch = [_imu(0.1, 0.0), Measurement("radar", 0.1, ("range_m",), np.ones(1), np.eye(1)),
             *_same_instant(0.1, 0.0)[::2]]  # imu, radar, gnss, steering
    assert [m.sensor for m in batch] == ["imu", "radar", "gnss", "steering"]
    assert linear_first(batch, kf._models) == [2, 3, 0, 1]
