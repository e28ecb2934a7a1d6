"""Each baseline's law against numbers a reader can check by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosim.core.config_fields import from_dict
from tracker.baselines import lqr
from tracker.baselines.common import bicycle, curvature_feedforward
from tracker.baselines.pid import pid_steer
from tracker.baselines.pure_pursuit import goal_point, lookahead_m, pursuit_curvature
from tracker.baselines.stanley import stanley_steer
from tracker.config import TrackerConfig
from tracker.paths.reference_path import ReferencePath


def test_stanley_steers_back_for_a_known_offset_and_heading_error() -> None:
    # Front axle 0.5 m left of the path, pointing 0.1 rad left, 10 m/s, k = 1.5, k_soft = 1:
    # delta = -0.1 - atan(1.5 * 0.5 / 11) = -0.1 - 0.068076 = -0.168076 rad.
    assert stanley_steer(0.1, 0.5, 10.0, 1.5, 1.0) == pytest.approx(-0.168076, abs=1e-6)
    # On the path and aligned it does nothing; the yaw-rate damping adds -k_d (r - r_ref).
    assert stanley_steer(0.0, 0.0, 10.0, 1.5, 1.0) == 0.0
    assert stanley_steer(0.0, 0.0, 10.0, 1.5, 1.0, 0.2, 0.1) == pytest.approx(-0.02)
    # At standstill the offset term is bounded by atan(k e / k_soft).
    assert stanley_steer(0.0, 2.0, 0.0, 1.5, 1.0) == pytest.approx(-math.atan(3.0))


def test_pure_pursuit_curvature_is_coulters_arc() -> None:
    # A goal point 10 m away, 30 degrees left of the heading: kappa = 2 sin(30 deg) / 10.
    assert pursuit_curvature(math.radians(30.0), 10.0) == pytest.approx(0.1)
    # The arc through the rear axle (origin, heading +x) and the goal point has that radius:
    # the centre (0, R) is R from both.
    goal = 10.0 * np.array([math.cos(math.radians(30.0)), math.sin(math.radians(30.0))])
    radius = 1.0 / pursuit_curvature(math.radians(30.0), 10.0)
    assert math.hypot(goal[0], goal[1] - radius) == pytest.approx(radius)


def test_pure_pursuit_lookahead_is_scheduled_by_speed_and_bounded() -> None:
    cfg = from_dict(TrackerConfig, {}).baseline.pure_pursuit
    assert lookahead_m(20.0, cfg) == pytest.approx(cfg.lookahead_min_m + 20.0
                                                   * cfg.lookahead_time_s)
    assert lookahead_m(0.0, cfg) == cfg.lookahead_min_m
    assert lookahead_m(1000.0, cfg) == cfg.lookahead_max_m


def test_pure_pursuit_goal_point_lies_on_the_path_at_the_lookahead() -> None:
    x = np.arange(0.0, 100.0, 1.0)
    path = ReferencePath(x, np.full_like(x, 2.0), 10.0)
    gx, gy = goal_point(path, 10.0, 0.0, 5.0)
    assert gy == pytest.approx(2.0, abs=1e-6)
    assert math.hypot(gx - 10.0, gy) == pytest.approx(5.0, abs=0.3)
    assert gx > 10.0


def test_pid_law_adds_its_terms_with_iso_signs() -> None:
    # 0.2 m left, drifting left at 0.5 m/s, heading 0.05 rad left, feed-forward 0.01 rad.
    steer = pid_steer(0.2, 0.5, 0.1, 0.05, 0.01, kp=0.15, ki=0.02, kd=0.08, k_heading=0.8)
    assert steer == pytest.approx(0.01 - 0.03 - 0.002 - 0.04 - 0.04)


def test_curvature_feedforward_is_ackermann_plus_understeer() -> None:
    params = bicycle(from_dict(TrackerConfig, {}))
    kappa, v = 1.0 / 40.0, 20.0
    expected = (params.wheelbase_m + params.understeer_gradient_radpmps2 * v * v) * kappa
    assert curvature_feedforward(kappa, v, params) == pytest.approx(expected)
    assert curvature_feedforward(kappa, 0.0, params) == pytest.approx(params.wheelbase_m / 40)


def _riccati_by_iteration(a: np.ndarray, b: np.ndarray, q: np.ndarray,
                          r: np.ndarray) -> np.ndarray:
    """P of the discrete Riccati equation by iterating the Riccati difference equation."""
    p = q.copy()
    for _ in range(20000):
        gain = np.linalg.solve(r + b.T @ p @ b, b.T @ p @ a)
        new = q + a.T @ p @ (a - b @ gain)
        if np.max(np.abs(new - p)) < 1e-12 * max(1.0, np.max(np.abs(p))):
            return new
        p = new
    raise AssertionError("Riccati iteration did not converge")


@pytest.mark.parametrize("speed_mps", [5.0, 20.0, 35.0])
def test_lqr_gain_matches_the_riccati_solution_and_stabilises(speed_mps: float) -> None:
    config = from_dict(TrackerConfig, {})
    params = bicycle(config)
    a, b = lqr.discretise(*lqr.path_error_matrices(params, speed_mps), config.dt_s)
    q, r = lqr.weights(config.baseline.lqr)
    p = _riccati_by_iteration(a, b, q, r)
    expected = np.linalg.solve(r + b.T @ p @ b, b.T @ p @ a)
    np.testing.assert_allclose(lqr.lqr_gain(a, b, q, r), expected, rtol=1e-6, atol=1e-9)
    assert np.max(np.abs(np.linalg.eigvals(a - b @ expected))) < 1.0


def test_lqr_schedule_interpolates_between_table_speeds() -> None:
    config = from_dict(TrackerConfig, {})
    law = lqr.LqrLaw(config)
    table = law.schedule
    mid = 0.5 * (table.speeds_mps[10] + table.speeds_mps[11])
    np.testing.assert_allclose(table.gain(mid), 0.5 * (table.gains[10] + table.gains[11]))


def test_zero_order_hold_matches_the_matrix_exponential_of_a_double_integrator() -> None:
    a = np.array([[0.0, 1.0], [0.0, 0.0]])
    b = np.array([[0.0], [1.0]])
    a_d, b_d = lqr.discretise(a, b, 0.1)
    np.testing.assert_allclose(a_d, [[1.0, 0.1], [0.0, 1.0]])
    np.testing.assert_allclose(b_d, [[0.005], [0.1]])


def test_lqr_feedforward_leaves_no_steady_state_offset_in_its_own_model() -> None:
    # Rajamani eq. (3.12): with delta = -K x + delta_ff on a steady turn, the model's
    # steady state has e1 = 0. Solve (A - B K) x + B delta_ff + B2 v kappa = 0 for x.
    config = from_dict(TrackerConfig, {})
    params = bicycle(config)
    v, kappa = 15.0, 1.0 / 60.0
    a, b = lqr.path_error_matrices(params, v)
    q, r = lqr.weights(config.baseline.lqr)
    gain = lqr.lqr_gain(*lqr.discretise(a, b, config.dt_s), q, r)
    m, iz = params.mass_kg, params.yaw_inertia_kgm2
    lf, lr = params.cog_front_m, params.cog_rear_m
    cf, cr = params.cornering_stiffness_front_npr, params.cornering_stiffness_rear_npr
    b2 = np.array([0.0, -(cf * lf - cr * lr) / (m * v) - v, 0.0,
                   -(cf * lf**2 + cr * lr**2) / (iz * v)])
    ff = lqr.lqr_feedforward(params, v, kappa, float(gain[0, 2]))
    closed = a - b @ gain
    x = np.linalg.solve(closed, -(b[:, 0] * ff + b2 * v * kappa))
    assert abs(x[0]) < 1e-9
