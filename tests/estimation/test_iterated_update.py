"""The iterated EKF update (:meth:`estimation.ekf.Ekf._joint_update`): a Gauss-Newton step
on the update's MAP cost, repeated while the models are not linear over the step; and the
start of a run, which a single linearisation at a prior drawn a few degrees of steering off
made the EKF gate (and the UKF, fusing the IMU before the steering:
:meth:`estimation.ukf.Ukf.update_many`)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from cosim.core.records import Measurement
from cosim.simulation.scenario_config import load_config
from estimation.ekf import Ekf
from estimation.fusion import KalmanFusion
from estimation.innovation import CheckedMeasurement, residual_function
from estimation.registry import make_estimator
from estimation.state import state_index
from tests.estimation.test_joint_update import _filter as _joint_update_filter


def _filter(**settings: object) -> Ekf:
    """The lane change's filter of ``test_joint_update``, its steering believed 0.08 rad
    off."""
    filter_ = _joint_update_filter(**settings)
    mean = filter_._x.copy()
    mean[state_index("steer_rad")] += 0.08
    filter_._set_mean(mean)
    return filter_


def _checked(filter_: Ekf) -> list[CheckedMeasurement]:
    """The IMU and the steering sensor as the true car, driving straight, reports them."""
    truth = filter_._x.copy()
    truth[state_index("steer_rad")] -= 0.08
    measurements = []
    for sensor, names in (("imu", ("yaw_rate_radps", "ax_mps2", "ay_mps2")),
                          ("steering", ("steer_rad",))):
        model = filter_._models[sensor]
        h, _ = model.evaluate(truth)
        values = np.array([h[model.channels.index(name)] for name in names])
        measurements.append(Measurement(sensor, filter_.t_s, names, values, np.eye(len(names))))
    checked = [filter_._check(m) for m in measurements]
    assert all(isinstance(c, CheckedMeasurement) for c in checked)
    return checked  # type: ignore[return-value]


def _gradient_norm(filter_: Ekf, checked: list[CheckedMeasurement], x: np.ndarray) -> float:
    """The MAP cost's gradient at ``x``, ``P0^-1 (x - x0) - H(x)' R^-1 (z - h(x))``, in the
    prior's metric (zero at the update the iterated EKF converges to)."""
    x0, p0 = filter_._x, filter_._p
    gradient = np.linalg.solve(p0, x - x0)
    for c in checked:
        h, jacobian = c.model.evaluate(x)
        rows = list(c.selection.model_rows)
        residual = residual_function(c.selection.angle_rows)(c.z, h[rows])
        gradient -= jacobian[rows, :].T @ (residual / c.selection.model_variance)
    return float(np.sqrt(gradient @ p0 @ gradient))


@pytest.mark.parametrize("compiled", [True, False])
def test_iterating_finds_the_maximum_a_posteriori_update(compiled: bool) -> None:
    plain_filter = _filter(ekf_iterations=0, compiled=compiled)
    plain = plain_filter._joint_update(_checked(plain_filter))
    converged_filter = _filter(ekf_iterations=50, ekf_linearisation_tolerance=0.0,
                               compiled=compiled)
    converged = converged_filter._joint_update(_checked(converged_filter))
    default_filter = _filter(compiled=compiled)
    default = default_filter._joint_update(_checked(default_filter))
    assert plain is not None and converged is not None and default is not None
    # One linearisation at the prior is far from linear over its step ...
    assert plain.linearisation_error > 1.0
    plain_gradient = _gradient_norm(plain_filter, _checked(plain_filter), plain.mean)
    # ... iterated to the end, the update is the cost's stationary point ...
    assert _gradient_norm(plain_filter, _checked(plain_filter), converged.mean) < (
        1e-6 * plain_gradient)
    # ... and the default stops within its tolerance, most of the way there.
    assert default.linearisation_error <= default_filter._config.ekf_linearisation_tolerance
    assert _gradient_norm(plain_filter, _checked(plain_filter), default.mean) < (
        0.1 * plain_gradient)
    # The NIS stays the prior's (the gate's figure), whatever the iterations.
    assert default.nis == plain.nis == converged.nis


def test_an_update_linear_over_its_step_is_the_plain_one_to_the_bit() -> None:
    filter_ = _filter()
    plain_filter = _filter(ekf_iterations=0)
    # The steering alone: the model is the state itself.
    steering = _checked(filter_)[1:]
    iterated = filter_._joint_update(steering)
    plain = plain_filter._joint_update(_checked(plain_filter)[1:])
    assert iterated is not None and plain is not None
    assert iterated.linearisation_error < 1e-9
    assert np.array_equal(iterated.mean, plain.mean)
    assert np.array_equal(iterated.covariance, plain.covariance)


@pytest.mark.parametrize(("kind", "iterations", "in_order_given", "wrong"), [
    ("ekf", 5, False, False), ("ekf", 0, False, True),
    ("ukf", 5, False, False), ("ukf", 5, True, True)])
def test_a_start_two_sigma_off_in_steering_gates_nothing(
        kind: str, iterations: int, in_order_given: bool, wrong: bool) -> None:
    # A run's start: the prior's road-wheel angle 0.1 rad (two of its standard deviations)
    # off, the IMU, wheel speeds and steering every 10 ms, noise-free, from the true car
    # driving straight. The EKF linearised once at the prior (no iterations) gave the first
    # update's lateral acceleration innovation to the wrong states; the UKF fusing the IMU
    # before the steering (the order given, not the linear models first) drew its sigma
    # points for the IMU over the whole steering spread. Both left an error that gated the
    # next instants' steering or wheel speeds in closed loop (here, noise-free, the UKF's
    # shows in the IMU's NIS); done right, the filter has the truth after the first instant.
    config = load_config("lane-change", estimator=kind)
    filter_ = make_estimator(
        dataclasses.replace(config.estimator, ekf_iterations=iterations),
        config.initial, config.tracker.model)
    assert isinstance(filter_, KalmanFusion)
    fuse = ((lambda batch: [filter_.update(m) for m in batch]) if in_order_given
            else filter_.update_many)
    truth = filter_._x.copy()
    mean = truth.copy()
    mean[state_index("steer_rad")] += 2.0 * config.estimator.init_steer_sigma_rad
    filter_._set_mean(mean)
    reasons, nis = [], []
    for k in range(5):
        measurements = []
        for sensor in ("imu", "wheel_speed", "steering"):
            model = filter_._models[sensor]
            h, _ = model.evaluate(truth)
            measurements.append(Measurement(sensor, 0.01 * k, model.channels, h.ravel().copy(),
                                            np.eye(len(model.channels))))
        results = fuse(measurements)
        # One result per measurement, in the order given (3, 2 and 1 channels; done wrong,
        # a channel may be gated out of its measurement).
        assert len(results) == 3
        if not wrong:
            assert [r.dim for r in results] == [3, 2, 1]
        reasons += [r.reason for r in results]
        if k > 0:
            nis += [r.joint_nis / r.joint_dim for r in results if r.joint_dim]
        truth = filter_._process.step(truth, 0.01)[0].reshape(-1)
    if wrong:  # the first instant left an error: gated, or a NIS well above the truth's 0
        assert {"gate", "partial"} & set(reasons) or max(nis) > 0.3
    else:
        assert set(reasons) == {"accepted"}
        assert max(nis) < 0.1
