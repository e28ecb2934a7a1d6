"""``lqr``: discrete LQR on the path-error bicycle, gains scheduled by speed.

Rajamani, "Vehicle Dynamics and Control", 2nd ed., Springer 2012, section 2.5 (eq. 2.45) and
section 3.2: with ``e1`` the lateral offset of the centre of gravity (positive left), ``e2 =
psi - psi_des`` and the axle cornering stiffnesses ``C_f, C_r`` (both tyres of an axle; the
book's ``2 C_alpha``), the lateral dynamics at forward speed ``v`` are::

    x = [e1, e1', e2, e2']
    x' = A(v) x + B1 delta + B2 psi_des'
    A = [[0, 1, 0, 0],
         [0, -(C_f + C_r)/(m v), (C_f + C_r)/m, (-C_f l_f + C_r l_r)/(m v)],
         [0, 0, 0, 1],
         [0, -(C_f l_f - C_r l_r)/(I_z v), (C_f l_f - C_r l_r)/I_z,
             -(C_f l_f^2 + C_r l_r^2)/(I_z v)]]
    B1 = [0, C_f/m, 0, C_f l_f/I_z]

discretised with a zero-order hold over the control period (``expm``), and the gain
``K = (R + B'PB)^-1 B'PA`` from the discrete algebraic Riccati equation
(``scipy.linalg.solve_discrete_are``) on a table of speeds, interpolated linearly at the
estimated speed. The feed-forward that zeroes the steady-state ``e1`` in a turn of
curvature ``kappa`` is eq. (3.12)::

    delta_ff = L kappa + K_V v^2 kappa - k_3 (l_r kappa - l_f m v^2 kappa / (C_r L))
    K_V = l_r m / (C_f L) - l_f m / (C_r L)

and ``delta = -K x + delta_ff``. The states come from the estimate: ``e1`` the CTE,
``e1' = v_y + v_x e2``, ``e2`` the heading error, ``e2' = r - v_x kappa``. Tuning
(``tracker.baseline.lqr``): ``Q = diag(1, 0, 1, 0)``, ``R = 10``, the weights of Bryson's
rule for 1 m, 1 rad and 0.3 rad.
"""

from __future__ import annotations

import numpy as np

from tracker.baselines.common import BaselineTracker, LateralLaw, Pose, bicycle
from tracker.baselines.config import LqrConfig
from tracker.config import TrackerConfig
from tracker.models.dynamic_bicycle import DynamicBicycleParams
from tracker.paths.reference_path import ReferencePath

ERROR_STATES = ("e1_m", "e1_rate_mps", "e2_rad", "e2_rate_radps")
"""The path-error state, in vector order."""


def path_error_matrices(params: DynamicBicycleParams,
                        speed_mps: float) -> tuple[np.ndarray, np.ndarray]:
    """``(A, B1)`` of Rajamani's eq. (2.45) at ``speed_mps`` (module docstring)."""
    m, iz = params.mass_kg, params.yaw_inertia_kgm2
    lf, lr = params.cog_front_m, params.cog_rear_m
    cf, cr = params.cornering_stiffness_front_npr, params.cornering_stiffness_rear_npr
    v = speed_mps
    a = np.array([
        [0.0, 1.0, 0.0, 0.0],
        [0.0, -(cf + cr) / (m * v), (cf + cr) / m, (-cf * lf + cr * lr) / (m * v)],
        [0.0, 0.0, 0.0, 1.0],
        [0.0, -(cf * lf - cr * lr) / (iz * v), (cf * lf - cr * lr) / iz,
         -(cf * lf**2 + cr * lr**2) / (iz * v)],
    ])
    b = np.array([[0.0], [cf / m], [0.0], [cf * lf / iz]])
    return a, b


def discretise(a: np.ndarray, b: np.ndarray, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Zero-order hold: ``expm([[A, B], [0, 0]] dt)``."""
    from scipy.linalg import expm  # here: heavy, and for the LQR baseline only
    n, k = a.shape[0], b.shape[1]
    block = np.zeros((n + k, n + k))
    block[:n, :n], block[:n, n:] = a, b
    phi = expm(block * dt_s)
    return phi[:n, :n], phi[:n, n:]


def lqr_gain(a_d: np.ndarray, b_d: np.ndarray, q: np.ndarray, r: np.ndarray) -> np.ndarray:
    """``K = (R + B'PB)^-1 B'PA`` with ``P`` from the discrete algebraic Riccati equation."""
    from scipy.linalg import solve_discrete_are  # here: heavy, and for the LQR baseline only
    p = solve_discrete_are(a_d, b_d, q, r)
    return np.linalg.solve(r + b_d.T @ p @ b_d, b_d.T @ p @ a_d)


def weights(config: LqrConfig) -> tuple[np.ndarray, np.ndarray]:
    """``(Q, R)`` from ``tracker.baseline.lqr``."""
    return (np.diag([config.q_cte, config.q_cte_rate, config.q_heading,
                     config.q_heading_rate]), np.array([[config.r_steer]]))


class GainSchedule:
    """LQR gains on a table of speeds, interpolated linearly (clamped at the ends)."""

    def __init__(self, params: DynamicBicycleParams, config: LqrConfig, dt_s: float) -> None:
        self.speeds_mps = np.arange(config.min_speed_mps,
                                    config.max_speed_mps + 0.5 * config.speed_step_mps,
                                    config.speed_step_mps)
        q, r = weights(config)
        self.gains = np.array([
            lqr_gain(*discretise(*path_error_matrices(params, v), dt_s), q, r)[0]
            for v in self.speeds_mps])

    def gain(self, speed_mps: float) -> np.ndarray:
        return np.array([np.interp(speed_mps, self.speeds_mps, self.gains[:, i])
                         for i in range(self.gains.shape[1])])


def lqr_feedforward(params: DynamicBicycleParams, speed_mps: float, curvature_1pm: float,
                    k3: float) -> float:
    """Rajamani's eq. (3.12) with axle stiffnesses (module docstring)."""
    m, lf, lr = params.mass_kg, params.cog_front_m, params.cog_rear_m
    cf, cr, length = (params.cornering_stiffness_front_npr,
                      params.cornering_stiffness_rear_npr, params.wheelbase_m)
    v2 = speed_mps**2
    kv = lr * m / (cf * length) - lf * m / (cr * length)
    return (length * curvature_1pm + kv * v2 * curvature_1pm
            - k3 * (lr * curvature_1pm - lf * m * v2 * curvature_1pm / (cr * length)))


class LqrLaw(LateralLaw):
    def __init__(self, config: TrackerConfig) -> None:
        self._cfg = config.baseline.lqr
        self._params = bicycle(config)
        self.schedule = GainSchedule(self._params, self._cfg, config.dt_s)

    def steer(self, pose: Pose, reference: ReferencePath, dt_s: float) -> float:
        v = max(pose.vx_mps, self._cfg.min_speed_mps)
        kappa = pose.projection.curvature_1pm
        e2 = pose.heading_error_rad
        state = np.array([pose.projection.lateral_error_m, pose.vy_mps + pose.vx_mps * e2,
                          e2, pose.yaw_rate_radps - pose.vx_mps * kappa])
        gain = self.schedule.gain(v)
        return float(-gain @ state + lqr_feedforward(self._params, v, kappa,
                                                     float(gain[ERROR_STATES.index("e2_rad")])))


def make_lqr(config: TrackerConfig) -> BaselineTracker:
    return BaselineTracker(config, LqrLaw(config))
