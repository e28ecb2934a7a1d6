"""Synthetic drives for the estimator tests: a dynamic-bicycle truth, noisy sensors, a run.

The truth is integrated here in numpy, independently of estimation/process_model.py, from
prescribed steering and longitudinal-acceleration profiles: the dynamic bicycle (Rajamani, "Vehicle
Dynamics and Control", section 2.3) with the tyre law ``F = mu F_z tanh(C alpha / (mu F_z))`` (or
linear), the belief's mass, inertia, CoG position and cornering stiffnesses, for the point on the
roll axis below the CoG; and a second-order body roll driven by the tyres' lateral acceleration,
which sways the CoG sideways by ``h phi`` (the MuJoCo sedan's numbers:
:data:`ROLL_GRADIENT_RADPMPS2` ...). Sensors sample it on an integer-millisecond clock with a
seeded numpy Generator: GNSS at 10 Hz, IMU and steering at 100 Hz, wheel speeds at 100 Hz offset by
5 ms, so the filter sees measurements out of one common rhythm.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from cosim.core.initial_state import InitialState
from cosim.core.records import WHEEL_NAMES, Measurement
from cosim.core.vehicle_params import VehicleParams
from cosim.plant.sedan_model import ackermann_angles
from estimation.bicycle import (
    DEFAULT_CORNERING_STIFFNESS_FRONT_NPR,
    DEFAULT_CORNERING_STIFFNESS_REAR_NPR,
)
from estimation.config import EstimatorConfig
from estimation.registry import make_estimator
from estimation.state import STATE_NAMES, wrap_angle

TRUTH_STEP_S = 1e-3
GNSS_PERIOD_MS = 100
IMU_PERIOD_MS = 10
STEERING_PERIOD_MS = 10
WHEEL_PERIOD_MS = 10
WHEEL_OFFSET_MS = 5
GRAVITY_MPS2 = 9.81

IMU_YAW_RATE_SIGMA_RADPS = 0.003
IMU_ACCEL_SIGMA_MPS2 = 0.05
WHEEL_SIGMA_RADPS = 0.05
STEERING_SIGMA_RAD = 0.001
REAR_DRIVE_SLIP_PER_MPS2 = 0.01
"""Drive slip of the (driven, ignored) rear wheels per m/s^2 of acceleration."""
ROLL_GRADIENT_RADPMPS2 = 0.0100
ROLL_FREQUENCY_HZ = 1.47
ROLL_DAMPING_RATIO = 0.51
"""The body roll mode of the MuJoCo sedan (estimation/config.py derives the same numbers)."""

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
    """Prescribed inputs: road-wheel angle and kinematic longitudinal acceleration."""

    name: str
    duration_s: float
    speed0_mps: float
    steer_rad: Callable[[float], float]
    accel_mps2: Callable[[float], float]


@functools.cache
def lane_change(peak_steer_rad: float = 0.045) -> Profile:
    """Accelerate 15 -> ~17.6 m/s, then a double lane change, 15 s.

    The default peak steer gives yaw rates of about 0.2 rad/s and 3.5 m/s^2 of lateral
    acceleration (mildly nonlinear: the tanh tyres give 4 % less force than linear ones).
    """
    period_s = 2.5
    return Profile(
        name="lane-change",
        duration_s=15.0,
        speed0_mps=15.0,
        steer_rad=lambda t: peak_steer_rad * (
            _sine_cycle(t, 4.0, period_s) - _sine_cycle(t, 9.0, period_s)
        ),
        accel_mps2=lambda t: 1.5 * _smooth_bump(t, 0.5, 3.5),
    )


@functools.cache
def circle(steer_rad: float = 0.06, speed_mps: float = 15.0, duration_s: float = 20.0) -> Profile:
    """Steer into a steady turn over 1 s (0.06 rad at 15 m/s: ~0.24 rad/s, 3.6 m/s^2)."""
    return Profile(
        name="circle",
        duration_s=duration_s,
        speed0_mps=speed_mps,
        steer_rad=lambda t: steer_rad * min(1.0, max(0.0, t - 1.0)),
        accel_mps2=lambda t: 0.0,
    )


@dataclass(frozen=True)
class Truth:
    """The true trajectory on the 1 ms grid, by VehicleState field name."""

    t_s: np.ndarray
    values: dict[str, np.ndarray]

    def at(self, index_ms: int, name: str) -> float:
        return float(self.values[name][index_ms])


def _tyre_force_n(
    stiffness_npr: float, slip_rad: float, load_n: float, friction: float, saturating: bool
) -> float:
    linear = stiffness_npr * slip_rad
    if not saturating:
        return linear
    limit = friction * load_n
    return limit * math.tanh(linear / limit)


@functools.cache
def simulate_truth(
    profile: Profile,
    initial: InitialState,
    belief: VehicleParams,
    saturating: bool = True,
    roll_gradient_radpmps2: float = ROLL_GRADIENT_RADPMPS2,
) -> Truth:
    """Integrate the dynamic bicycle and the roll mode (RK4 at 1 ms) driven by the
    profile's inputs; report the motion of the CoG as VehicleState does. Cached (the
    profiles are too): callers must not modify the arrays."""
    m, i_z = belief.mass_kg, belief.yaw_inertia_kgm2
    l_f, l_r = belief.cog_front_m, belief.cog_rear_m
    c_f = getattr(belief, "cornering_stiffness_front_npr", DEFAULT_CORNERING_STIFFNESS_FRONT_NPR)
    c_r = getattr(belief, "cornering_stiffness_rear_npr", DEFAULT_CORNERING_STIFFNESS_REAR_NPR)
    load_f = m * GRAVITY_MPS2 * l_r / (l_f + l_r)
    load_r = m * GRAVITY_MPS2 * l_f / (l_f + l_r)
    mu = belief.tyre_friction
    omega = 2.0 * math.pi * ROLL_FREQUENCY_HZ
    arm_m = belief.cog_height_m if roll_gradient_radpmps2 > 0.0 else 0.0

    def forces(state: np.ndarray, steer: float) -> tuple[float, float]:
        _, _, _, vx, vy_axis, r, _, _ = state
        alpha_f = steer - (vy_axis + l_f * r) / vx
        alpha_r = -(vy_axis - l_r * r) / vx
        return (
            _tyre_force_n(c_f, alpha_f, load_f, mu, saturating),
            _tyre_force_n(c_r, alpha_r, load_r, mu, saturating),
        )

    def roll_accel(state: np.ndarray, lateral_accel: float) -> float:
        roll, roll_rate = state[6], state[7]
        return (-omega**2 * (roll - roll_gradient_radpmps2 * lateral_accel)
                - 2.0 * ROLL_DAMPING_RATIO * omega * roll_rate)

    def derivative(t_s: float, state: np.ndarray) -> np.ndarray:
        # The planar motion of the point on the roll axis below the CoG, and the roll.
        _, _, yaw, vx, vy_axis, r, _, roll_rate = state
        f_f, f_r = forces(state, profile.steer_rad(t_s))
        lateral_accel = (f_f + f_r) / m
        return np.array(
            [
                vx * math.cos(yaw) - vy_axis * math.sin(yaw),
                vx * math.sin(yaw) + vy_axis * math.cos(yaw),
                r,
                profile.accel_mps2(t_s) + r * vy_axis,
                lateral_accel - r * vx,
                (l_f * f_f - l_r * f_r) / i_z,
                roll_rate,
                roll_accel(state, lateral_accel),
            ]
        )

    steps = round(profile.duration_s / TRUTH_STEP_S)
    t = np.arange(steps + 1) * TRUTH_STEP_S
    states = np.empty((steps + 1, 8))
    states[0] = (initial.x_m, initial.y_m, initial.yaw_rad, initial.speed_mps, 0.0, 0.0, 0.0,
                 0.0)
    h = TRUTH_STEP_S
    for k in range(steps):
        tk, s = t[k], states[k]
        k1 = derivative(tk, s)
        k2 = derivative(tk + h / 2, s + h / 2 * k1)
        k3 = derivative(tk + h / 2, s + h / 2 * k2)
        k4 = derivative(tk + h, s + h * k3)
        states[k + 1] = s + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    steer = np.array([profile.steer_rad(tk) for tk in t])
    lateral = np.array([sum(forces(s, d)) / m for s, d in zip(states, steer, strict=True)])
    roll_accels = np.array([roll_accel(s, a) for s, a in zip(states, lateral, strict=True)])
    yaw, roll, roll_rate = states[:, 2], states[:, 6], states[:, 7]
    sway_m = -arm_m * roll  # the CoG moves right (-y) when the body rolls left side up
    return Truth(
        t_s=t,
        values={
            "x_m": states[:, 0] - sway_m * np.sin(yaw),
            "y_m": states[:, 1] + sway_m * np.cos(yaw),
            "yaw_rad": np.asarray(wrap_angle(yaw)),
            "vx_mps": states[:, 3],
            "vy_mps": states[:, 4] - arm_m * roll_rate,
            "vy_axis_mps": states[:, 4],
            "yaw_rate_radps": states[:, 5],
            "ax_mps2": np.array([profile.accel_mps2(tk) for tk in t]),
            "ay_mps2": lateral - arm_m * roll_accels,  # = vy' + r vx at the CoG
            "steer_rad": steer,
            "roll_rad": roll,
        },
    )


@dataclass(frozen=True)
class SensorSetup:
    """Noise, biases and faults of the synthetic sensors."""

    gnss_sigma_m: float = 0.02
    gnss_velocity_sigma_mps: float | None = None
    """GNSS (Doppler) velocity with this noise at the fixes' times; None: no such sensor."""
    gnss_outage_s: tuple[float, float] | None = None
    """GNSS silent in [start, end)."""
    gnss_outlier_at_s: float | None = None
    gnss_outlier_m: float = 20.0
    gnss_offset_from_s: float | None = None
    """From this time on every GNSS fix is offset by ``gnss_outlier_m`` (persistent fault)."""
    nan_imu_at_s: float | None = None
    gyro_bias_radps: float = 0.0
    ax_bias_mps2: float = 0.0
    ay_bias_mps2: float = 0.0
    use_imu: bool = True
    use_wheels: bool = True
    use_steering: bool = True
    rolling_radius_scale: float = 1.0
    """True effective rolling radius over the believed one (the filter starts at 1)."""


def _ms(t_s: float) -> int:
    return round(t_s * 1000.0)


def synthesize(
    truth: Truth, belief: VehicleParams, setup: SensorSetup, rng: np.random.Generator
) -> list[Measurement]:
    """Every sensor's measurements, sorted by time (gnss, imu, steering, wheels on ties)."""
    # One child generator per sensor: turning a sensor off does not change another's noise.
    gnss_rng, imu_rng, wheel_rng, steering_rng, velocity_rng = rng.spawn(5)
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
        if setup.gnss_velocity_sigma_mps is not None:
            yaw, vx, vy = (truth.at(index, n) for n in ("yaw_rad", "vx_mps", "vy_mps"))
            velocity = np.array([vx * math.cos(yaw) - vy * math.sin(yaw),
                                 vx * math.sin(yaw) + vy * math.cos(yaw)])
            sigma = setup.gnss_velocity_sigma_mps
            measurements.append((index, 0, Measurement(
                "gnss_velocity", t_s, ("v_east_mps", "v_north_mps"),
                velocity + velocity_rng.normal(0.0, sigma, 2), np.eye(2) * sigma**2)))

    imu_names = ("yaw_rate_radps", "ax_mps2", "ay_mps2")
    imu_sigma = np.array([IMU_YAW_RATE_SIGMA_RADPS, IMU_ACCEL_SIGMA_MPS2, IMU_ACCEL_SIGMA_MPS2])
    imu_bias = np.array([setup.gyro_bias_radps, setup.ax_bias_mps2, setup.ay_bias_mps2])
    for index in range(IMU_PERIOD_MS, last_ms + 1, IMU_PERIOD_MS):
        values = np.array([truth.at(index, n) for n in imu_names]) + imu_bias
        values = values + imu_rng.normal(0, imu_sigma)
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

    for index in range(STEERING_PERIOD_MS, last_ms + 1, STEERING_PERIOD_MS):
        value = truth.at(index, "steer_rad") + steering_rng.normal(0.0, STEERING_SIGMA_RAD)
        if setup.use_steering:
            cov = np.eye(1) * STEERING_SIGMA_RAD**2
            measurement = Measurement(
                "steering", index / 1000.0, ("steer_rad",), np.array([value]), cov
            )
            measurements.append((index, 2, measurement))

    wheel_names = tuple(f"{w}_radps" for w in WHEEL_NAMES)
    track_front, track_rear = belief.axle_tracks_m
    for index in range(WHEEL_OFFSET_MS, last_ms + 1, WHEEL_PERIOD_MS):
        vx, vy, r, ax, steer = (
            truth.at(index, n) for n in ("vx_mps", "vy_axis_mps", "yaw_rate_radps", "ax_mps2",
                                         "steer_rad")
        )
        # Front wheels: the centre's velocity along the wheel's own (Ackermann) plane.
        left, right = ackermann_angles(steer, belief.wheelbase_m, track_front)
        front_lateral = vy + r * belief.cog_front_m
        slip = 1.0 + REAR_DRIVE_SLIP_PER_MPS2 * ax  # driven rear wheels spin faster
        speeds = np.array(
            [
                (vx - 0.5 * r * track_front) * math.cos(left) + front_lateral * math.sin(left),
                (vx + 0.5 * r * track_front) * math.cos(right) + front_lateral * math.sin(right),
                (vx - 0.5 * r * track_rear) * slip,
                (vx + 0.5 * r * track_rear) * slip,
            ]
        )
        radius_m = belief.wheel_radius_m * setup.rolling_radius_scale
        values = speeds / radius_m + wheel_rng.normal(0.0, WHEEL_SIGMA_RADPS, 4)
        if setup.use_wheels:
            cov = np.eye(4) * WHEEL_SIGMA_RADPS**2
            measurements.append(
                (index, 3, Measurement("wheel_speed", index / 1000.0, wheel_names, values, cov))
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

    def state(self, name: str) -> np.ndarray:
        return self.means[:, STATE_NAMES.index(name)]

    def sigma(self, name: str) -> np.ndarray:
        index = STATE_NAMES.index(name)
        return np.sqrt(self.covariances[:, index, index])

    def error(self, name: str) -> np.ndarray:
        """Estimate minus truth (wrapped for yaw) at every logged time."""
        true = self.truth.values[name][self.truth_index]
        difference = self.state(name) - true
        return np.asarray(wrap_angle(difference)) if name == "yaw_rad" else difference

    def settled(self, after_s: float = 1.0) -> np.ndarray:
        return self.t_s >= after_s

    def position_error_m(self) -> np.ndarray:
        return np.hypot(self.error("x_m"), self.error("y_m"))

    def position_rmse_m(self, mask: np.ndarray | None = None) -> float:
        mask = self.settled() if mask is None else mask
        return float(np.sqrt(np.mean(self.position_error_m()[mask] ** 2)))

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
    estimator: str = "ekf",
    seed: int = 0,
    setup: SensorSetup | None = None,
    config: EstimatorConfig | None = None,
    initial: InitialState | None = None,
    saturating_truth: bool = True,
) -> Run:
    """Simulate ``profile``, synthesise the sensors, fuse everything with ``estimator``."""
    setup = SensorSetup() if setup is None else setup
    config = EstimatorConfig(name=estimator) if config is None else config
    # The filter believes the synthetic sensors' datasheet (no quantisation here), and the
    # synthetic tyres, whose forces follow their slip angles at once (no relaxation), each
    # axle's at the axle's load (a bicycle: no lateral load transfer).
    config = dataclasses.replace(config, tyre_relaxation_length_front_m=0.0,
                                 tyre_relaxation_length_rear_m=0.0,
                                 lateral_load_transfer=False, noise=dataclasses.replace(
        config.noise, gnss_sigma_m=setup.gnss_sigma_m, gyro_sigma_radps=IMU_YAW_RATE_SIGMA_RADPS,
        accel_sigma_mps2=IMU_ACCEL_SIGMA_MPS2, wheel_sigma_radps=WHEEL_SIGMA_RADPS,
        wheel_quantum_radps=0.0, steer_sigma_rad=STEERING_SIGMA_RAD, steer_quantum_rad=0.0))
    initial = InitialState(speed_mps=profile.speed0_mps) if initial is None else initial
    belief = VehicleParams()
    truth = simulate_truth(profile, initial, belief, saturating_truth)
    measurements = synthesize(truth, belief, setup, np.random.default_rng(seed))
    filter_ = make_estimator(config, initial, belief)
    times, indices, means, covariances = [], [], [], []
    nis: dict[str, list[float]] = {}
    reasons: list[tuple[float, str, str]] = []
    log_every = IMU_PERIOD_MS
    next_log_ms = log_every
    for measurement in measurements:
        index = _ms(measurement.t_s)
        while next_log_ms < index:
            # Log on a fixed 100 Hz grid whether or not the IMU is in use.
            filter_.predict(next_log_ms / 1000.0)
            estimate = filter_.estimate()
            times.append(estimate.t_s)
            indices.append(next_log_ms)
            means.append(estimate.mean)
            covariances.append(estimate.covariance)
            next_log_ms += log_every
        result = filter_.update(measurement)
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
        counts=filter_.counts(),
        reasons=reasons,
    )
