"""Settings of the ``dynamic-mpc`` tracker: ``tracker.dynamic_mpc``.

The defaults are the reference design of :mod:`tracker.mpc.dynamic_mpc` (Np = 10, Nc = 2,
Ts = 0.1 s, its bounds and soft limits).

The cost is the reference design's sum over stages (not an integral over time, unlike
``tracker.weights``), so each weight multiplies the square of an SI quantity once per
stage::

    J = sum_{j=1..Np} [ w_speed (vx_j - v_D)^2 + w_lateral e1_j^2 + w_heading e2_j^2 ]
      + sum_{i=0..Nc-1} [ w_accel_increment (Delta a_i)^2
                          + w_steer_increment (Delta delta_i)^2 ]
      + w_slack sum_{c, j} (eps_cj^2 + eps_cj)

with ``eps_cj >= 0`` the slack of soft limit ``c`` at node ``j`` (lateral error in m,
heading error in rad, speed in m/s). With the linear term and a weight this large the
penalty is exact: a limit that can be met is met. The defaults and the measurements
behind them are in :mod:`tracker.mpc.dynamic_mpc`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from cosim.core.config_fields import setting
from cosim.core.exceptions import ConfigError

QP_SOLVERS: tuple[str, ...] = ("highs", "daqp")
"""CasADi QP back-ends (``conic`` plugins) the dynamic MPC can use (the choice and the
measurements: :mod:`tracker.mpc.dynamic_mpc`)."""


STEER_AFTER_CONTROL_HORIZON: tuple[str, ...] = ("held", "path")
"""What the steering does after the control horizon (:mod:`tracker.mpc.dynamic_mpc`,
item 3)."""


@dataclass(frozen=True)
class DynamicMpcConfig:
    """The delta-u MPC on the dynamic bicycle with path-error states
    (:mod:`tracker.mpc.dynamic_mpc`)."""

    prediction_horizon: int = setting(10, low=1, high=200, doc="Np, stages predicted")
    control_horizon: int = setting(
        2, low=1, high=200, doc="Nc, input moves decided (the input is held after them)"
    )
    sample_time_s: float = setting(0.1, low=0.005, high=1.0, doc="Ts, length of one stage [s]")
    accel_time_constant_s: float = setting(
        0.1,
        low=0.001,
        high=5.0,
        doc="first-order lag of the achieved acceleration behind the command; the reference design "
        "ties it to the sample time [s]",
    )
    weight_speed: float = setting(
        1.0, low=0.0, high=1e9, doc="(vx - v_D)^2 per stage [1/(m/s)^2]"
    )
    weight_lateral: float = setting(
        100.0, low=0.0, high=1e9, doc="lateral error e1^2 per stage [1/m^2]"
    )
    weight_heading: float = setting(
        1000.0, low=0.0, high=1e9, doc="heading error e2^2 per stage [1/rad^2]"
    )
    weight_accel_increment: float = setting(
        10.0, low=1e-9, high=1e9, doc="acceleration increment (Delta a)^2 [1/(m/s^2)^2]"
    )
    weight_steer_increment: float = setting(
        2500.0, low=1e-9, high=1e9, doc="steering increment (Delta delta)^2 [1/rad^2]"
    )
    weight_slack: float = setting(
        1e5,
        low=0.0,
        high=1e12,
        doc="slack of each soft limit at each node, squared plus linear, in the limit's "
        "SI unit (m, rad, m/s)",
    )
    max_lateral_error_m: float = setting(
        0.5, low=0.01, high=100.0,
        doc="soft limit |e1| (reference design: 0.5 m; lane 4 m, car 2 m)",
    )
    max_heading_error_rad: float = setting(
        math.radians(3.0), low=0.001, high=math.pi, doc="soft limit |e2| (reference design: 3 deg)"
    )
    min_speed_mps: float = setting(0.0, low=0.0, high=100.0, doc="soft lower speed limit")
    max_speed_mps: float = setting(30.0, low=0.1, high=100.0, doc="soft upper speed limit")
    steer_after_control_horizon: str = setting(
        "path", choices=STEER_AFTER_CONTROL_HORIZON,
        doc="the steering from stage Nc on: 'held' (the reference design: the last move "
        "held) or 'path' (the last move's offset from the path's Ackermann angle "
        "atan(L kappa) held, so the steering follows the curvature ahead)",
    )
    qp_solver: str = setting("highs", choices=QP_SOLVERS, doc="CasADi QP back-end")
    max_iterations: int = setting(
        1000,
        low=1,
        high=100000,
        doc="QP iteration limit (HiGHS counts every bound it fixes: about 40 per step at "
        "Np = 10, growing with the 3 Np slacks)",
    )

    def __post_init__(self) -> None:
        if self.control_horizon > self.prediction_horizon:
            raise ConfigError(
                f"control_horizon = {self.control_horizon}: expected at most "
                f"prediction_horizon = {self.prediction_horizon}"
            )
        if not self.min_speed_mps < self.max_speed_mps:
            raise ConfigError(
                f"min_speed_mps = {self.min_speed_mps}: expected less than "
                f"max_speed_mps = {self.max_speed_mps}"
            )
