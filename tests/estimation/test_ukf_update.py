"""The UKF's sigma points and update are filterpy's, written out on arrays: the same numbers
as filterpy's MerweScaledSigmaPoints and UnscentedKalmanFilter.update, to the bit."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter

from cosim.simulation.scenario_config import load_config
from cosim.simulation.seeding import component_rng
from cosim.simulation.workshop import Workshop
from estimation.state import STATE_NAMES
from estimation.ukf import ScaledSigmaPoints, Ukf, at_points

N = len(STATE_NAMES)


def _covariance(rng: np.random.Generator) -> np.ndarray:
    """A random, well-spread positive definite covariance of the filter's size."""
    a = rng.normal(size=(N, N)) * np.exp(rng.uniform(-4.0, 1.0, N))
    return a @ a.T + 1e-6 * np.eye(N)


@pytest.mark.parametrize(("alpha", "beta", "kappa"), [(1.0, 2.0, 0.0), (0.3, 2.0, 1.0)])
def test_the_sigma_points_are_filterpys_to_the_bit(alpha: float, beta: float,
                                                  kappa: float) -> None:
    rng = np.random.default_rng(4)
    ours = ScaledSigmaPoints(N, alpha, beta, kappa)
    theirs = MerweScaledSigmaPoints(N, alpha, beta, kappa)
    for _ in range(50):
        x, p = rng.normal(size=N) * 10.0, _covariance(rng)
        assert np.array_equal(ours.sigma_points(x, p), theirs.sigma_points(x, p))
    assert np.array_equal(ours.Wm, theirs.Wm) and np.array_equal(ours.Wc, theirs.Wc)


def test_bad_covariances_raise_as_filterpys_do() -> None:
    ours = ScaledSigmaPoints(N, 1.0, 2.0, 0.0)
    theirs = MerweScaledSigmaPoints(N, 1.0, 2.0, 0.0)
    indefinite = np.eye(N)
    indefinite[3, 3] = -1.0
    for points in (ours, theirs):
        with pytest.raises(np.linalg.LinAlgError, match="4-th leading minor"):
            points.sigma_points(np.zeros(N), indefinite)
        with pytest.raises(ValueError, match="infs or NaNs"):
            points.sigma_points(np.zeros(N), np.full((N, N), np.nan))


def _filter(compiled: bool) -> Ukf:
    config = load_config("lane-change", estimator="ukf",
                         overrides=[f"estimator.compiled={str(compiled).lower()}"])
    filter_ = Workshop().estimator(config.estimator, config.initial, config.tracker.model,
                                   component_rng(3, "estimator.initial"))
    assert isinstance(filter_, Ukf)
    return filter_


@pytest.mark.parametrize("compiled", [True, False])
def test_the_update_is_filterpys_to_the_bit(compiled: bool) -> None:
    """Every measurement model (the heading's an angle channel, averaged on the circle), all
    its channels and a part of them: mean, covariance, innovation and its covariance equal
    to filterpy's ``UnscentedKalmanFilter.update`` of the same filter through a point-by-point
    ``hx``, from a spread-out belief, with the models compiled and in CasADi's virtual
    machine."""
    filter_ = _filter(compiled)
    rng = np.random.default_rng(9)
    kf = filter_._kf
    kf.P = kf.P + 0.1 * _covariance(rng)
    for sensor, model in filter_._models.items():
        n = len(model.channels)
        angle_rows = tuple(i for i, c in enumerate(model.channels) if c in model.angle_channels)
        for rows in {tuple(range(n)), tuple(range(0, n, 2))}:
            index = list(rows)
            z = model.value(kf.x)[index] + rng.normal(size=len(rows)) * 0.1
            r = np.diag(rng.uniform(0.01, 0.1, len(rows)))
            ours = filter_._trial_update(model, rows, z, r, np.subtract,
                                         tuple(rows.index(i) for i in angle_rows if i in rows))
            # filterpy's update method on the filter itself (its angle means and residuals
            # as the UKF set them for this update), point by point, then the belief back
            x, p = kf.x, kf.P
            kf.sigmas_f = MerweScaledSigmaPoints(N, 1.0, 2.0, 0.0).sigma_points(x, p)
            UnscentedKalmanFilter.update(kf, z, R=r,
                                         hx=lambda point, i=index, m=model: m.value(point)[i])
            reference = kf.x, kf.P, kf.y, kf.S
            kf.x, kf.P = x, p
            assert np.array_equal(ours.mean, reference[0]), sensor
            assert np.array_equal(ours.covariance, reference[1]), sensor
            assert np.array_equal(ours.innovation, reference[2]), sensor
            assert np.array_equal(ours.innovation_covariance, reference[3]), sensor


def test_a_model_at_every_sigma_point_is_each_point_alone() -> None:
    filter_ = _filter(False)
    points = filter_._points.sigma_points(filter_._kf.x, filter_._kf.P)
    for model in filter_._models.values():
        values = model.value_function
        mapped = at_points(values.function, points.shape[0])
        together = np.asarray(mapped(points.T, values.parameters)).T
        alone = np.array([model.value(p) for p in points])
        assert np.array_equal(together, alone)


def test_the_models_mapped_over_the_sigma_points_share_their_subexpressions(
        monkeypatch: pytest.MonkeyPatch) -> None:
    # The UKF's library calls the sub-step and the measurement models through maps, which
    # code generation leaves as they are: built with their repeated subexpressions shared,
    # the C computes each once (the wheel speeds' model 511 -> 325 operations).
    from cosim.core.compiled_function import subexpressions_shared
    from cosim.core.vehicle_params import VehicleParams
    from cosim.simulation.runner import run_unlogged
    from estimation import measurement_models, process_model

    models = measurement_models.build_measurement_models.__wrapped__(  # not the cached
        VehicleParams(), 0.1, 0.1)
    assert {"imu", "wheel_speed"} <= set(models)
    for sensor, model in models.items():
        function = model.value_function.function
        assert subexpressions_shared(function) is function, sensor
    built: list[ca.Function] = []
    uncached = process_model._process_functions.__wrapped__

    def spied(*args: object) -> object:
        functions = uncached(*args)
        built.append(functions.mean_step)
        return functions

    monkeypatch.setattr(process_model, "_process_functions", spied)
    run_unlogged(load_config("lane-change", overrides=[
        "estimator.name=ukf", "estimator.compiled=false"], duration_s=0.1))
    assert {function.name() for function in built} == {"bicycle_mean_step"}
    for function in built:
        assert subexpressions_shared(function) is function
