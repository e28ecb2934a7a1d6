"""The EKF's predict and update are filterpy's algorithm: the same results as
``ExtendedKalmanFilter.predict`` and ``.update``."""

from __future__ import annotations

import numpy as np
import pytest
from filterpy.kalman import ExtendedKalmanFilter

from estimation.ekf import covariance_prediction, joseph_update
from estimation.innovation import residual_function
from estimation.state import wrap_angle


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


def test_covariance_prediction_is_filterpys() -> None:
    rng = np.random.default_rng(7)
    n = 16
    square = rng.normal(size=(n, n))
    p = square @ square.T
    transition = np.eye(n) + 0.01 * rng.normal(size=(n, n))
    noise = np.diag(rng.uniform(1e-6, 1e-3, size=n))
    filterpy_ekf = ExtendedKalmanFilter(dim_x=n, dim_z=1)
    filterpy_ekf.P, filterpy_ekf.F, filterpy_ekf.Q = p.copy(), transition, noise
    filterpy_ekf.predict()
    np.testing.assert_allclose(covariance_prediction(p, transition, noise), filterpy_ekf.P,
                               rtol=1e-13, atol=1e-15)


def test_the_joint_noise_matrix_is_scipys_block_diagonal() -> None:
    import scipy.linalg

    from estimation.ekf import block_diagonal

    rng = np.random.default_rng(4)
    blocks = [np.diag(rng.random(3)), rng.random((2, 2)), np.diag(rng.random(1))]
    assert np.array_equal(block_diagonal(blocks), scipy.linalg.block_diag(*blocks))
