"""The EKF's predict and update are filterpy's algorithm: the same results as
``ExtendedKalmanFilter.predict`` (the covariance of the one-call sub-step) and ``.update``."""

from __future__ import annotations

import math

import numpy as np
import pytest
from filterpy.kalman import ExtendedKalmanFilter

from estimation.bicycle import BicycleParams
from estimation.ekf import joseph_update
from estimation.innovation import residual_function
from estimation.process_model import ProcessModel
from estimation.state import STATE_NAMES, state_index, wrap_angle
from tests.estimation.test_models import BELIEF, NOISE, ROLL


@pytest.mark.parametrize("dim_z, angle_rows", [(1, ()), (2, ()), (3, (1,))])
def test_joseph_update_gives_filterpys_posterior(dim_z: int, angle_rows: tuple[int, ...]) -> None:
    rng = np.random.default_rng(dim_z)
    n = 16
    square = rng.normal(size=(n, n))
    p = square @ square.T + 0.1 * np.eye(n)
    x = rng.normal(size=n)
    jacobian = rng.normal(size=(dim_z, n))
    r_matrix = np.diag(rng.uniform(0.01, 1.0, size=dim_z))
    h = rng.normal(size=dim_z)
    z = h + rng.normal(size=dim_z)
    if angle_rows:  # an angle innovation across +-pi: the residual must wrap it
        h[angle_rows[0]], z[angle_rows[0]] = 3.1, -3.1
    residual = residual_function(angle_rows)

    filterpy_ekf = ExtendedKalmanFilter(dim_x=n, dim_z=dim_z)
    filterpy_ekf.x, filterpy_ekf.P = x.reshape(-1, 1).copy(), p.copy()
    filterpy_ekf.update(
        z.reshape(-1, 1), HJacobian=lambda _x: jacobian, Hx=lambda _x: h.reshape(-1, 1),
        R=r_matrix, residual=lambda a, b: residual(a.reshape(-1), b.reshape(-1)).reshape(-1, 1),
    )
    ours = joseph_update(x, p, z, h, jacobian, r_matrix, residual)

    np.testing.assert_allclose(ours.mean, filterpy_ekf.x.reshape(-1), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(ours.covariance, filterpy_ekf.P, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(ours.innovation, filterpy_ekf.y.reshape(-1), atol=1e-15)
    np.testing.assert_allclose(ours.innovation_covariance, filterpy_ekf.S, rtol=1e-13)
    if angle_rows:
        assert ours.innovation[angle_rows[0]] == pytest.approx(wrap_angle(-6.2))
    # The inputs are not modified.
    assert ours.mean is not x and not np.shares_memory(ours.covariance, p)


@pytest.mark.parametrize("accel_move", [(0.0, 0.0), (0.3, 0.02)])
def test_the_sub_step_predicts_the_covariance_as_filterpy(
        accel_move: tuple[float, float]) -> None:
    # The EKF's one-call sub-step against its pieces: the acceleration moved, the model's
    # own sub-step (x1, F, Q) and filterpy's predict of the covariance, then wrapped and
    # symmetrised. A yaw just under pi steps across it: the mean comes back wrapped.
    model = ProcessModel(NOISE, BicycleParams.from_vehicle(BELIEF, "saturating", ROLL), 0.5)
    rng = np.random.default_rng(7)
    n = len(STATE_NAMES)
    square = rng.normal(size=(n, n))
    p = 1e-3 * (square @ square.T) + 1e-4 * np.eye(n)
    x = np.zeros(n)
    x[state_index("vx_mps")], x[state_index("yaw_rate_radps")] = 15.0, 0.4
    x[state_index("yaw_rad")] = math.pi - 1e-3
    ax = state_index("ax_mps2")
    moved_x, moved_p = x.copy(), p.copy()
    moved_x[ax] += accel_move[0]
    moved_p[ax, ax] += accel_move[1]
    dt_s = 0.01
    x1, transition, noise = model.step(moved_x, dt_s, 0.02)
    filterpy_ekf = ExtendedKalmanFilter(dim_x=n, dim_z=1)
    filterpy_ekf.P, filterpy_ekf.F, filterpy_ekf.Q = moved_p.copy(), transition, noise
    filterpy_ekf.predict()

    mean, covariance = model.covariance_step(x, p, dt_s, 0.02, accel_move)

    expected = x1.reshape(-1).copy()
    expected[state_index("yaw_rad")] = wrap_angle(float(expected[state_index("yaw_rad")]))
    assert expected[state_index("yaw_rad")] < 0.0  # it did cross pi
    np.testing.assert_allclose(mean, expected, rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(covariance, 0.5 * (filterpy_ekf.P + filterpy_ekf.P.T),
                               rtol=1e-12, atol=1e-15)
    assert np.array_equal(covariance, covariance.T)


def test_the_joint_noise_matrix_is_scipys_block_diagonal() -> None:
    import scipy.linalg

    from estimation.ekf import block_diagonal

    rng = np.random.default_rng(4)
    blocks = [np.diag(rng.random(3)), rng.random((2, 2)), np.diag(rng.random(1))]
    assert np.array_equal(block_diagonal(blocks), scipy.linalg.block_diag(*blocks))
