"""The EKF's joint update of an instant's measurements as one compiled function
(:mod:`estimation.joint_update`): the posterior and the NIS of the numpy joint update for
every combination of sensors and channels, and the same runs through ``update_many``."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from cosim.core.records import Measurement
from cosim.simulation.scenario_config import load_config
from estimation.ekf import Ekf
from estimation.fusion import KalmanFusion
from estimation.innovation import CheckedMeasurement
from estimation.registry import make_estimator
from tests.conftest import run_scenario

T_S = 0.5
"""Where the filter is predicted to before the update: the covariance has correlations."""


def _filter(**settings: object) -> Ekf:
    config = load_config("lane-change")
    estimator_config = dataclasses.replace(config.estimator, **settings)
    filter_ = make_estimator(estimator_config, config.initial, config.tracker.model,
                             rng=np.random.default_rng(4))
    assert isinstance(filter_, Ekf)
    filter_.predict(T_S)
    return filter_


def _measurement(filter_: Ekf, sensor: str, names: tuple[str, ...],
                 offsets: tuple[float, ...]) -> Measurement:
    """A measurement of ``names`` at the predicted mean plus ``offsets``."""
    model = filter_._models[sensor]
    h, _ = model.evaluate(filter_._x)
    values = np.array([h[model.channels.index(name)] for name in names]) + offsets
    return Measurement(sensor, T_S, names, values, np.eye(len(names)))


def _checked(filter_: Ekf, measurements: list[Measurement]) -> list[CheckedMeasurement]:
    checked = [filter_._check(m) for m in measurements]
    assert all(isinstance(c, CheckedMeasurement) for c in checked)
    return checked  # type: ignore[return-value]


def _both(filter_: Ekf, measurements: list[Measurement],
          at: np.ndarray | None = None) -> tuple[object, object]:
    """One update linearised at ``at`` (None: the mean), compiled and in numpy."""
    checked = _checked(filter_, measurements)
    compiled = filter_._linearised_update(checked, at)
    numpy_path = filter_._posterior(checked, at)
    return compiled, numpy_path


def _relative(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


def _cases(filter_: Ekf) -> dict[str, list[Measurement]]:
    wheels = filter_._models["wheel_speed"].channels
    return {
        "imu, wheels, steering": [
            _measurement(filter_, "imu", ("yaw_rate_radps", "ax_mps2", "ay_mps2"),
                         (0.02, -0.3, 0.4)),
            _measurement(filter_, "wheel_speed", wheels, (0.5,) * len(wheels)),
            _measurement(filter_, "steering", ("steer_rad",), (0.01,)),
        ],
        "and the GNSS, channels in another order": [
            _measurement(filter_, "gnss", ("y_m", "x_m"), (-0.7, 1.2)),
            _measurement(filter_, "imu", ("ay_mps2", "yaw_rate_radps", "ax_mps2"),
                         (0.4, 0.02, -0.3)),
            _measurement(filter_, "steering", ("steer_rad",), (-0.02,)),
        ],
        "some channels only": [
            _measurement(filter_, "imu", ("yaw_rate_radps",), (0.05,)),
            _measurement(filter_, "wheel_speed", wheels[:1], (0.3,)),
            _measurement(filter_, "gnss_velocity", ("v_north_mps",), (0.2,)),
        ],
        "a heading across +-pi": [
            _measurement(filter_, "heading", ("yaw_rad",), (2.0 * math.pi - 0.05,)),
            _measurement(filter_, "gnss", ("x_m", "y_m"), (0.3, 0.1)),
        ],
    }


def test_the_compiled_joint_update_is_the_numpy_one_for_every_combination() -> None:
    filter_ = _filter()
    assert filter_._joint_function.function.compiled
    # Linearised at the mean, and elsewhere (an iterated update's later linearisations).
    elsewhere = filter_._x + 3.0 * np.sqrt(np.diag(filter_._p))
    for name, measurements in _cases(filter_).items():
        for at in (None, elsewhere):
            compiled, numpy_path = _both(filter_, measurements, at)
            assert compiled is not None and numpy_path is not None, name
            assert _relative(compiled.mean, numpy_path.mean) < 1e-9, name
            assert _relative(compiled.covariance, numpy_path.covariance) < 1e-9, name
            assert np.array_equal(compiled.covariance, compiled.covariance.T), name
            assert np.allclose(compiled.nis, numpy_path.nis, rtol=1e-9, atol=0.0), name
            assert compiled.linearisation_error == pytest.approx(
                numpy_path.linearisation_error, rel=1e-6, abs=1e-12), name
        # The plain numpy update of the fusion base class: the same at the mean.
        compiled = _both(filter_, measurements)[0]
        plain = KalmanFusion._joint_update(filter_, _checked(filter_, measurements))
        assert _relative(compiled.mean, plain.mean) < 1e-9, name
        # Each measurement changed the belief: no channel was dropped by the mask.
        for m in measurements:
            alone = _both(filter_, [m])[1]
            assert abs(alone.nis[0] - compiled.nis[measurements.index(m)]) < 1e-9 * max(
                1.0, alone.nis[0]), name


def test_the_angle_channel_is_wrapped_and_a_repeated_sensor_is_left_to_the_caller() -> None:
    filter_ = _filter()
    cases = _cases(filter_)
    heading = cases["a heading across +-pi"]
    compiled = filter_._joint_update(_checked(filter_, heading[:1]))
    # 2 pi - 0.05 off is 0.05 off: a small innovation, not a jump of almost a turn.
    yaw = filter_.state_names.index("yaw_rad")
    noise = filter_._check(heading[0]).selection.model_variance[0]
    assert compiled.nis[0] == pytest.approx(0.05 ** 2 / (filter_._p[yaw, yaw] + noise),
                                            rel=1e-9)
    twice = [cases["imu, wheels, steering"][0], cases["some channels only"][0]]
    assert filter_._joint_update(_checked(filter_, twice)) is None


def test_runs_through_update_many_are_those_of_the_numpy_update(tmp_path: Path) -> None:
    # Four seconds of the lane change (IMU, wheels and steering every 10 ms, the GNSS
    # every 50): the compiled joint update against the numpy one, every metric.
    (tmp_path / "compiled").mkdir()
    (tmp_path / "numpy").mkdir()
    compiled = run_scenario(tmp_path / "compiled", "lane-change", duration_s=4.0, seed=6)
    numpy_path = run_scenario(tmp_path / "numpy", "lane-change", "estimator.compiled=false",
                              duration_s=4.0, seed=6)
    compared = 0
    for key, value in numpy_path.metrics.items():
        if "ms" in key or "time" in key or "realtime" in key or not isinstance(value, float):
            continue
        other = compiled.metrics[key]
        if math.isnan(value):
            assert math.isnan(other), key
            continue
        assert other == pytest.approx(value, rel=1e-9, abs=1e-12), key
        compared += 1
    assert compared > 15
    assert compiled.metrics["nees_mean"] != numpy_path.metrics["nees_mean"] or \
        compiled.metrics["nis_mean"] != numpy_path.metrics["nis_mean"]


@pytest.mark.parametrize("compiled", [True, False])
def test_update_many_commits_an_exactly_symmetric_covariance(compiled: bool) -> None:
    """The compiled joint update's covariance is symmetric to the bit and is committed as it
    is; the numpy path's products are symmetric only to rounding and are symmetrised before
    they are committed, as every update's are."""
    for case in ("imu, wheels, steering", "some channels only"):
        filter_ = _filter(compiled=compiled)
        measurements = _cases(filter_)[case]
        joint = filter_._joint_update(_checked(filter_, measurements))
        assert joint is not None and joint.symmetric == compiled, case
        results = filter_.update_many(measurements)
        assert all(r.accepted for r in results), case
        assert np.array_equal(filter_._x, joint.mean), case  # the joint update, committed
        covariance = filter_._p
        assert np.array_equal(covariance, covariance.T), case


def _factorises(matrix: np.ndarray) -> bool:
    """numpy's (LAPACK's) verdict: finite and positive definite."""
    if not np.isfinite(matrix).all():
        return False
    try:
        np.linalg.cholesky(matrix)
    except np.linalg.LinAlgError:
        return False
    return True


def test_the_compiled_positive_definiteness_is_lapacks_verdict() -> None:
    """The joint update says whether its covariance is finite and positive definite, so the
    commit need not factorise it again: the flag agrees with ``numpy.linalg.cholesky`` on
    well- and ill-conditioned, semi-definite, indefinite and non-finite matrices."""
    import casadi as ca

    from estimation.joint_update import _cholesky_pivots_positive

    n = 17
    symbol = ca.SX.sym("a", n, n)
    flag = ca.Function("flag", [symbol], [_cholesky_pivots_positive(symbol)])
    rng = np.random.default_rng(3)
    cases = []
    for scale in (1.0, 1e-8, 1e6):
        root = rng.normal(size=(n, n))
        cases.append(scale * (root @ root.T + 0.1 * np.eye(n)))
    graded = np.diag(np.logspace(-14, 2, n))
    cases.append(graded)
    rank_short = rng.normal(size=(n, n - 2))
    cases.append(rank_short @ rank_short.T)  # semi-definite
    indefinite = cases[0].copy()
    indefinite[5, 5] = -1.0
    cases.append(indefinite)
    last_negative = cases[0].copy()
    last_negative[-1, -1] -= 1e3
    cases.append(last_negative)
    cases.append(np.diag([1.0] * (n - 1) + [0.0]))  # a pivot of exactly zero
    for bad in (np.nan, np.inf):
        for where in ((0, 0), (3, 7), (n - 1, n - 1)):
            broken = cases[0].copy()
            broken[where] = broken[where[::-1]] = bad
            cases.append(broken)
    verdicts = [float(flag(case)) == 1.0 for case in cases]
    assert verdicts == [_factorises(case) for case in cases]
    # positive definite (however scaled or graded) yes; indefinite or non-finite no (the
    # semi-definite one is rounding's to decide: both decide alike)
    assert verdicts[:4] == [True] * 4 and not any(verdicts[5:])


def test_a_committed_joint_update_was_found_positive_definite() -> None:
    filter_ = _filter()
    for case in ("imu, wheels, steering", "some channels only"):
        joint = filter_._joint_update(_checked(filter_, _cases(filter_)[case]))
        assert joint is not None and joint.positive_definite, case
    plain = KalmanFusion._joint_update(filter_, _checked(filter_, _cases(filter_)[case]))
    assert plain is not None and not plain.positive_definite  # unchecked: _commit factorises
