"""Synthetic drives for the estimator tests: truth from kinematics, noisy sensors, a run.

The truth is integrated here, independently of the filter, from prescribed yaw-rate,
acceleration and sideslip profiles (the same kinematic equations as the EKF's process model,
see estimation/models.py). Sensors sample it on an integer-millisecond clock with a seeded
numpy Generator: GNSS at 10 Hz, IMU at 100 Hz, wheel speeds at 100 Hz offset by 5 ms so the
filter sees measurements out of one common rhythm.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from cosim.initial_state import InitialState
from cosim.records import WHEEL_NAMES, Measurement
from cosim.vehicle_params import VehicleParams
from estimation.config import EstimatorConfig
from estimation.ekf import Ekf
from estimation.models import STATE_NAMES, wrap_angle

TRUTH_STEP_S = 1e-3
GNSS_PERIOD_MS = 100
IMU_PERIOD_MS = 10
WHEEL_PERIOD_MS = 10
WHEEL_OFFSET_MS = 5

IMU_YAW_RATE_SIGMA_RADPS = 0.003
IMU_ACCEL_SIGMA_MPS2 = 0.05
WHEEL_SIGMA_RADPS = 0.05

NEES_STATES: tuple[str, ...] = ("x_m", "y_m", "yaw_rad", "vx_mps")


def _smooth_bump(t_s: float, start_s: float, duration_s: float) -> float:
    """sin^2 bump from 0 to 1 and back to 0 over [start, start + duration]."""
    if not start_s <= t_s <= start_s + duration_s:
        return 0.0
    return math.sin(math.pi * (t_s - start_s) / duration_s) ** 2


def _sine_cycle(t_s: float, start_s: float, period_s: float) -> float:
    """One full sine period over [start, start + period], zero elsewhere."""
    if not start_s <= t_s <= start_s + period_s:
        return 0.0
    return math.sin(2.0 * math.pi * (t_s - start_s) / period_s)


@dataclass(frozen=True)
class Profile:
    """Prescribed motion: yaw rate, longitudinal acceleration, sideslip, over time."""

    name: str
    duration_s: float
    speed0_mps: float
    yaw_rate_radps: Callable[[float], float]
    accel_mps2: Callable[[float], float]
    lateral_velocity_mps: Callable[[float, float, float], float] = (
        lambda t_s, vx_mps, yaw_rate_radps: 0.0
    )
    """vy as a function of time, vx and yaw rate (0: the plain CTRA truth)."""


def lane_change(sideslip_gain_s: float = 0.0) -> Profile:
    """Accelerate 15 -> ~17.6 m/s, then a double lane change (~3.5 m each way), 15 s.

    With ``sideslip_gain_s`` != 0 the car also slips sideways, ``vy = -gain * vx * r``
    (a sedan above its characteristic speed points its nose into the turn).
    """
    peak_yaw_rate_radps = 0.2
    period_s = 2.5
    return Profile(
        name="lane-change",
        duration_s=15.0,
        speed0_mps=15.0,
        yaw_rate_radps=lambda t: (
            peak_yaw_rate_radps * (_sine_cycle(t, 4.0, period_s) - _sine_cycle(t, 9.0, period_s))
        ),
        accel_mps2=lambda t: 1.5 * _smooth_bump(t, 0.5, 3.5),
        lateral_velocity_mps=lambda t, vx, r: -sideslip_gain_s * vx * r,
    )


def circle(
    radius_m: float = 40.0, speed_mps: float = 15.0, sideslip_gain_s: float = 0.0
) -> Profile:
    """Enter a circle of ``radius_m`` over 1 s and keep going round, 20 s.

    ``sideslip_gain_s`` as in :func:`lane_change` (a steady sideslip on the circle).
    """
    yaw_rate = speed_mps / radius_m

    def yaw_rate_radps(t_s: float) -> float:
        return yaw_rate * min(1.0, max(0.0, t_s - 1.0))

    return Profile(
        name="circle",
        duration_s=20.0,
        speed0_mps=speed_mps,
        yaw_rate_radps=yaw_rate_radps,
        accel_mps2=lambda t: 0.0,
        lateral_velocity_mps=lambda t, vx, r: -sideslip_gain_s * vx * r,
    )


@dataclass(frozen=True)
class Truth:
    """The true trajectory on the 1 ms grid, by VehicleState field name."""

    t_s: np.ndarray
    values: dict[str, np.ndarray]

    def at(self, index_ms: int, name: str) -> float:
        return float(self.values[name][index_ms])


def simulate_truth(profile: Profile, initial: InitialState) -> Truth:
    """Integrate the kinematics (RK4 at 1 ms) for the prescribed profiles."""
    steps = round(profile.duration_s / TRUTH_STEP_S)
    t = np.arange(steps + 1) * TRUTH_STEP_S

    def lateral(t_s: float, vx: float) -> float:
        return profile.lateral_velocity_mps(t_s, vx, profile.yaw_rate_radps(t_s))

    def derivative(t_s: float, pose: np.ndarray) -> np.ndarray:
        x, y, yaw, vx = pose
        r = profile.yaw_rate_radps(t_s)
        vy = lateral(t_s, vx)
        return np.array(
            [
                vx * math.cos(yaw) - vy * math.sin(yaw),
                vx * math.sin(yaw) + vy * math.cos(yaw),
                r,
                profile.accel_mps2(t_s) + r * vy,
            ]
        )

    poses = np.empty((steps + 1, 4))
    poses[0] = (initial.x_m, initial.y_m, initial.yaw_rad, initial.speed_mps)
    h = TRUTH_STEP_S
    for k in range(steps):
        tk, p = t[k], poses[k]
        k1 = derivative(tk, p)
        k2 = derivative(tk + h / 2, p + h / 2 * k1)
        k3 = derivative(tk + h / 2, p + h / 2 * k2)
        k4 = derivative(tk + h, p + h * k3)
        poses[k + 1] = p + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)

    vx = poses[:, 3]
    r = np.array([profile.yaw_rate_radps(tk) for tk in t])
    vy = np.array([lateral(tk, v) for tk, v in zip(t, vx, strict=True)])
    ax = np.array([profile.accel_mps2(tk) for tk in t])  # kinematic: dvx/dt - r vy
    vy_dot = np.gradient(vy, TRUTH_STEP_S)
    return Truth(
        t_s=t,
        values={
            "x_m": poses[:, 0],
            "y_m": poses[:, 1],
            "yaw_rad": np.asarray(wrap_angle(poses[:, 2])),
            "vx_mps": vx,
            "vy_mps": vy,
            "yaw_rate_radps": r,
            "ax_mps2": ax,
            "ay_mps2": vy_dot + r * vx,
        },
    )


@dataclass(frozen=True)
class SensorSetup:
    """Noise and faults of the synthetic sensors."""

    gnss_sigma_m: float = 0.02
    gnss_outage_s: tuple[float, float] | None = None
    """GNSS silent in [start, end)."""
    gnss_outlier_at_s: float | None = None
    gnss_outlier_m: float = 20.0
    gnss_offset_from_s: float | None = None
    """From this time on every GNSS fix is offset by ``gnss_outlier_m`` (persistent fault)."""
    nan_imu_at_s: float | None = None
    use_imu: bool = True
    use_wheels: bool = True
    rolling_radius_scale: float = 1.0
    """True effective rolling radius over the believed one (the filter starts at 1)."""


def _ms(t_s: float) -> int:
    return round(t_s * 1000.0)


def synthesize(
    truth: Truth, belief: VehicleParams, setup: SensorSetup, rng: np.random.Generator
) -> list[Measurement]:
    """Every sensor's measurements, sorted by time (gnss, imu, wheels on ties)."""
    # One child generator per sensor: turning a sensor off does not change another's noise.
    gnss_rng, imu_rng, wheel_rng = rng.spawn(3)
    last_ms = len(truth.t_s) - 1
    measurements: list[tuple[int, int, Measurement]] = []

    for index in range(GNSS_PERIOD_MS, last_ms + 1, GNSS_PERIOD_MS):
        t_s = index / 1000.0
        noise = gnss_rng.normal(0.0, setup.gnss_sigma_m, 2)
        if setup.gnss_outage_s and setup.gnss_outage_s[0] <= t_s < setup.gnss_outage_s[1]:
            continue
        values = np.array([truth.at(index, "x_m"), truth.at(index, "y_m")]) + noise
        if setup.gnss_outlier_at_s is not None and index == _ms(setup.gnss_outlier_at_s):
            values += setup.gnss_outlier_m  # both axes: the whole fix is wrong
        if setup.gnss_offset_from_s is not None and index >= _ms(setup.gnss_offset_from_s):
            values[0] += setup.gnss_outlier_m
        cov = np.eye(2) * setup.gnss_sigma_m**2
        measurements.append((index, 0, Measurement("gnss", t_s, ("x_m", "y_m"), values, cov)))

    imu_names = ("yaw_rate_radps", "ax_mps2", "ay_mps2")
    imu_sigma = np.array([IMU_YAW_RATE_SIGMA_RADPS, IMU_ACCEL_SIGMA_MPS2, IMU_ACCEL_SIGMA_MPS2])
    for index in range(IMU_PERIOD_MS, last_ms + 1, IMU_PERIOD_MS):
        values = np.array([truth.at(index, n) for n in imu_names]) + imu_rng.normal(0, imu_sigma)
        if setup.nan_imu_at_s is not None and index == _ms(setup.nan_imu_at_s):
            values[1] = math.nan
        if setup.use_imu:
            measurements.append(
                (
                    index,
                    1,
                    Measurement("imu", index / 1000.0, imu_names, values, np.diag(imu_sigma**2)),
                )
            )

    wheel_names = tuple(f"{w}_radps" for w in WHEEL_NAMES)
    half_track = 0.5 * belief.track_m
    for index in range(WHEEL_OFFSET_MS, last_ms + 1, WHEEL_PERIOD_MS):
        vx, vy, r = (truth.at(index, n) for n in ("vx_mps", "vy_mps", "yaw_rate_radps"))
        # Front wheels roll along their own (steered) direction: centre speed magnitude.
        front_lateral = vy + r * belief.cog_front_m
        speeds = np.array(
            [
                math.hypot(vx - r * half_track, front_lateral),
                math.hypot(vx + r * half_track, front_lateral),
                vx - r * half_track,
                vx + r * half_track,
            ]
        )
        radius_m = belief.wheel_radius_m * setup.rolling_radius_scale
        values = speeds / radius_m + wheel_rng.normal(0.0, WHEEL_SIGMA_RADPS, 4)
        if setup.use_wheels:
            cov = np.eye(4) * WHEEL_SIGMA_RADPS**2
            measurements.append(
                (index, 2, Measurement("wheel_speed", index / 1000.0, wheel_names, values, cov))
            )
    measurements.sort(key=lambda item: (item[0], item[1]))
    return [m for _, _, m in measurements]


@dataclass
class Run:
    """A filter run: estimates at 100 Hz beside the truth, and every update result."""

    t_s: np.ndarray
    truth_index: np.ndarray
    means: np.ndarray
    covariances: np.ndarray
    truth: Truth
    nis: dict[str, list[float]] = field(default_factory=dict)
    counts: dict[str, dict[str, int]] = field(default_factory=dict)
    reasons: list[tuple[float, str, str]] = field(default_factory=list)

    def error(self, name: str) -> np.ndarray:
        """Estimate minus truth (wrapped for yaw) at every logged time."""
        estimate = self.means[:, STATE_NAMES.index(name)]
        true = self.truth.values[name][self.truth_index]
        difference = estimate - true
        return np.asarray(wrap_angle(difference)) if name == "yaw_rad" else difference

    def settled(self, after_s: float = 1.0) -> np.ndarray:
        return self.t_s >= after_s

    def position_rmse_m(self, mask: np.ndarray | None = None) -> float:
        mask = self.settled() if mask is None else mask
        squared = self.error("x_m") ** 2 + self.error("y_m") ** 2
        return float(np.sqrt(np.mean(squared[mask])))

    def rmse(self, name: str, mask: np.ndarray | None = None) -> float:
        mask = self.settled() if mask is None else mask
        return float(np.sqrt(np.mean(self.error(name)[mask] ** 2)))

    def nees(self, names: tuple[str, ...] = NEES_STATES) -> np.ndarray:
        idx = [STATE_NAMES.index(n) for n in names]
        errors = np.column_stack([self.error(n) for n in names])
        values = np.empty(len(self.t_s))
        for k in range(len(self.t_s)):
            sub = self.covariances[k][np.ix_(idx, idx)]
            values[k] = errors[k] @ np.linalg.solve(sub, errors[k])
        return values


def run_filter(
    profile: Profile,
    *,
    seed: int = 0,
    setup: SensorSetup | None = None,
    config: EstimatorConfig | None = None,
    initial: InitialState | None = None,
) -> Run:
    """Simulate ``profile``, synthesise the sensors, fuse everything with the EKF."""
    setup = SensorSetup() if setup is None else setup
    config = EstimatorConfig() if config is None else config
    initial = InitialState(speed_mps=profile.speed0_mps) if initial is None else initial
    belief = VehicleParams()
    truth = simulate_truth(profile, initial)
    measurements = synthesize(truth, belief, setup, np.random.default_rng(seed))
    ekf = Ekf(config, initial, belief)
    times, indices, means, covariances = [], [], [], []
    nis: dict[str, list[float]] = {}
    reasons: list[tuple[float, str, str]] = []
    log_every = IMU_PERIOD_MS
    next_log_ms = log_every
    for measurement in measurements:
        index = _ms(measurement.t_s)
        while next_log_ms < index:
            # Log on a fixed 100 Hz grid whether or not the IMU is in use.
            ekf.predict(next_log_ms / 1000.0)
            estimate = ekf.estimate()
            times.append(estimate.t_s)
            indices.append(next_log_ms)
            means.append(estimate.mean)
            covariances.append(estimate.covariance)
            next_log_ms += log_every
        result = ekf.update(measurement)
        if result.accepted:
            nis.setdefault(measurement.sensor, []).append(result.nis)
        if result.reason != "accepted":
            reasons.append((measurement.t_s, measurement.sensor, result.reason))
    return Run(
        t_s=np.array(times),
        truth_index=np.array(indices),
        means=np.array(means),
        covariances=np.array(covariances),
        truth=truth,
        nis=nis,
        counts=ekf.counts(),
        reasons=reasons,
    )
