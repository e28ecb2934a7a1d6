"""Tuning of the baseline trackers: the ``tracker.baseline:`` section.

Each law has its own sub-section; the speed loop is shared. The defaults were tuned on the
MuJoCo sedan (Magic Formula tyres, EKF in the loop, ``rtk`` sensors) over the lane change at
20 m/s, the 40 m circle and the ISO 3888-1 lane change, as a competent engineer would tune
them in an afternoon: each gain raised until the response on the lane change stopped
improving or began to oscillate on the straight from sensor noise, then backed off by
about a third. Figures are in the modules of each law.
"""

from __future__ import annotations

from dataclasses import dataclass

from cosim.core.config_fields import section, setting


@dataclass(frozen=True)
class SpeedLoopConfig:
    """Longitudinal PI on speed with the reference's acceleration as feed-forward."""

    kp: float = setting(1.0, low=0.0, high=100.0, doc="accel per speed error [1/s]")
    ki: float = setting(0.2, low=0.0, high=100.0, doc="accel per integrated error [1/s^2]")
    integral_limit_mps: float = setting(3.0, low=0.0, high=100.0,
                                        doc="anti-windup bound of the integrated error")


@dataclass(frozen=True)
class PidConfig:
    """Lateral PID on the cross-track error plus a heading term and curvature feed-forward."""

    kp_cte: float = setting(0.15, low=0.0, high=100.0, doc="steer per CTE [rad/m]")
    ki_cte: float = setting(0.02, low=0.0, high=100.0, doc="steer per integrated CTE [rad/(m s)]")
    kd_cte: float = setting(0.08, low=0.0, high=100.0,
                            doc="steer per CTE rate (v sin(heading error)) [rad s/m]")
    k_heading: float = setting(0.8, low=0.0, high=100.0, doc="steer per heading error [-]")
    integral_limit_ms: float = setting(2.0, low=0.0, high=100.0,
                                       doc="anti-windup bound of the integrated CTE [m s]")


@dataclass(frozen=True)
class StanleyConfig:
    """Stanley's law (Hoffmann et al. 2007) with its yaw-rate damping."""

    gain: float = setting(1.5, low=0.0, high=100.0, doc="k: gain on the front axle's CTE [1/s]")
    softening_mps: float = setting(1.0, low=0.01, high=100.0,
                                   doc="k_soft: keeps the gain finite at standstill")
    yaw_rate_damping: float = setting(0.1, low=0.0, high=10.0,
                                      doc="k_d,yaw: steer per yaw-rate error [s]")


@dataclass(frozen=True)
class PurePursuitConfig:
    """Pure pursuit (Coulter 1992) with a speed-scheduled look-ahead."""

    lookahead_time_s: float = setting(0.6, low=0.0, high=10.0,
                                      doc="look-ahead per speed: L_d = L_min + t_la v [s]")
    lookahead_min_m: float = setting(4.0, low=0.5, high=100.0, doc="L_min [m]")
    lookahead_max_m: float = setting(40.0, low=1.0, high=500.0, doc="L_d upper bound [m]")


@dataclass(frozen=True)
class LqrConfig:
    """Discrete LQR on Rajamani's path-error model, gains scheduled by speed."""

    q_cte: float = setting(1.0, low=0.0, high=1e6, doc="weight on e1^2 [1/m^2]")
    q_cte_rate: float = setting(0.0, low=0.0, high=1e6, doc="weight on e1'^2 [s^2/m^2]")
    q_heading: float = setting(1.0, low=0.0, high=1e6, doc="weight on e2^2 [1/rad^2]")
    q_heading_rate: float = setting(0.0, low=0.0, high=1e6, doc="weight on e2'^2 [s^2/rad^2]")
    r_steer: float = setting(10.0, low=1e-6, high=1e6, doc="weight on delta^2 [1/rad^2]")
    min_speed_mps: float = setting(3.0, low=0.5, high=50.0,
                                   doc="the gain table starts here (slower: this speed's gain)")
    max_speed_mps: float = setting(45.0, low=1.0, high=100.0, doc="the gain table ends here")
    speed_step_mps: float = setting(1.0, low=0.1, high=10.0, doc="spacing of the gain table")


@dataclass(frozen=True)
class BaselineConfig:
    """Tuning of the ``pid``, ``stanley``, ``pure-pursuit`` and ``lqr`` trackers."""

    speed: SpeedLoopConfig = section(SpeedLoopConfig)
    pid: PidConfig = section(PidConfig)
    stanley: StanleyConfig = section(StanleyConfig)
    pure_pursuit: PurePursuitConfig = section(PurePursuitConfig)
    lqr: LqrConfig = section(LqrConfig)
