"""Configuration of a state estimator: the ``estimator:`` section of a scenario.

Every key is a validated :func:`cosim.core.config_fields.setting`, so a scenario file or the
command line (``--set estimator.gate=false``, ``--set estimator.jerk_psd_m2ps5=10``) is
checked by :func:`cosim.core.config_fields.from_dict` and a bad value names its dotted key.

Process noise is given as continuous-time power spectral densities (PSD) of white noise
driving one state each; the filter integrates them over every prediction interval
(:mod:`estimation.process_model`), so the tuning does not depend on the sensor rates. A PSD ``q``
driving a state makes that state a random walk whose standard deviation grows as
``sqrt(q * t)``. Units: ``m2ps5`` is m^2/s^5 (jerk), ``rad2ps3`` rad^2/s^3 (yaw
acceleration), ``m2ps3`` m^2/s^3 (lateral acceleration), ``rad2ps`` rad^2/s, ``m2ps`` m^2/s,
``1ps`` 1/s (a dimensionless state: the rolling-radius scale); ``radpmps2`` is rad per m/s^2.

The defaults were set on the MuJoCo sedan (the default plant) from its logged truth: see
the module docstring of :mod:`estimation.process_model` and the comments below.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

from cosim.core.config_fields import mapping, section, setting
from cosim.core.exceptions import ConfigError
from cosim.core.plugins import entry_point_names, is_import_path
from estimation.bicycle import TYRE_MODELS
from estimation.noise_config import NoiseBelief

ESTIMATOR_NAMES: tuple[str, ...] = ("ekf", "ukf", "truth")
"""Built-in values of ``estimator.name``; :func:`estimation.registry.make_estimator` builds
each (and plug-ins: :data:`PLUGIN_GROUP`, or an import path)."""

PLUGIN_GROUP = "cosim.estimators"
"""Entry-point group of estimators from other packages."""


def is_plugin_name(name: str) -> bool:
    """Whether ``name`` names an estimator from outside cosim: an import path or a plug-in."""
    return is_import_path(name) or name in entry_point_names(PLUGIN_GROUP)

INITIAL_MODES: tuple[str, ...] = ("sampled", "first-fix", "truth")
"""Values ``estimator.initial`` accepts (:mod:`estimation.initial`)."""


@dataclass(frozen=True)
class EstimatorConfig:
    """The state estimator: which one, its process noise, initial uncertainty and gating."""

    name: str = setting(
        "ekf",
        doc="ekf: extended Kalman filter; ukf: unscented Kalman filter (same models); "
        "truth: the true state (debugging); or an estimator from outside cosim: an installed "
        "plug-in (entry point group cosim.estimators, `cosim estimators`) or an import path "
        "my_pkg.my_module:MyFilter (estimation.registry)",
    )
    params: dict[str, Any] = mapping(
        doc="a plug-in estimator's own settings (it reads them from its config.params)",
    )

    def __post_init__(self) -> None:
        if self.name not in ESTIMATOR_NAMES and not is_plugin_name(self.name):
            raise ConfigError(
                f"name = {self.name!r}: expected one of {', '.join(ESTIMATOR_NAMES)}, an "
                "installed plug-in (cosim estimators) or an import path module:Class"
            )

    initial: str = setting(
        "sampled",
        choices=INITIAL_MODES,
        doc="the initial estimate: sampled (drawn from N(truth, P0) with the run's seed), "
        "first-fix (sampled, then the position taken from the first GNSS fix) or truth "
        "(debugging only: the filter starts without error)",
    )
    noise: NoiseBelief = section(NoiseBelief)

    tyre_model: str = setting(
        "saturating",
        choices=TYRE_MODELS,
        doc="the bicycle's tyres: linear (C alpha), or saturating (C alpha limited smoothly at "
        "mu F_z of the static axle load)",
    )

    # Body roll (R2 of estimation.process_model). Defaults: the MuJoCo sedan's suspension
    # (models/README.md): roll stiffness 2 (k_f + k_r) (t/2)^2 = 92 570 N m/rad less the
    # sprung weight's m_s g h = 8 260 N m/rad, sprung mass 1495 kg at h = 0.563 m, roll
    # inertia 517 + m_s h^2 = 991 kg m^2, damping 2 (c_f + c_r) (t/2)^2 = 9 400 N m s/rad:
    # gradient m_s h / k = 0.0100 rad/(m/s^2), 1.47 Hz, damping ratio 0.51 (a least-squares
    # fit on the lane change's truth: 0.0092-0.0100 rad/(m/s^2), 1.1-1.9 Hz, 0.4-0.65).
    roll_gradient_radpmps2: float = setting(
        0.0100, low=0.0, high=0.1, doc="steady body roll per lateral acceleration (0: no roll)"
    )
    roll_frequency_hz: float = setting(1.47, low=0.1, high=5.0, doc="natural frequency of roll")
    roll_damping_ratio: float = setting(0.51, low=0.01, high=5.0, doc="damping ratio of roll")

    # Process noise (continuous-time white-noise PSDs).
    # The jerk's floor, the roll acceleration's force-dependent part and the wheels' model
    # error were re-identified channel by channel from the innovations (nu_i^2 / S_ii of the
    # gyro, each accelerometer, the wheel speeds), replaying the sensor streams of
    # lane-change ensembles on both suites (tuned on the tuning seeds of
    # bench/estimator_consistency.py, checked on seeds 6400-6439): with them as they were,
    # the IMU's settled NIS per dof was 0.80-0.82 and the wheels' 0.86-0.87, the states they
    # see holding a covariance two to three times their error on the straights; the jerk's
    # share of the manoeuvres (launch, braking) is now ``jerk_relative_psd_1ps``'s. The yaw
    # acceleration's floor stays: a third of it brought the gyro's NIS to 1 on the lane
    # change but doubled the ring's NEES (docs/defaults.md). Then, with the tyres'
    # relaxation in the model, every PSD here was halved and every model sigma divided by
    # sqrt(2) (docs/defaults.md, "The tyres' relaxation").
    jerk_psd_m2ps5: float = setting(
        0.005, low=0.0, high=1e6, doc="longitudinal jerk driving ax_mps2 [m^2/s^5]"
    )
    jerk_relative_psd_1ps: float = setting(
        0.15, low=0.0, high=1e4,
        doc="jerk PSD per squared longitudinal acceleration: ``jerk_psd_m2ps5 + this * "
        "a_x^2``, the drive and brake forces change with the force asked of them (launch, "
        "braking) and rest while the car cruises [1/s]",
    )
    # The drive's response to the controller's acceleration commands, an input of the
    # prediction (estimation.accel_commands): without it the acceleration is a random walk
    # the accelerometer corrects after each change of the command (a launch's first step
    # put the IMU's NIS in the hundreds and gated the wheels for the first second).
    accel_commands: bool = setting(
        True, doc="move the acceleration state with the controller's acceleration commands "
        "(estimation.accel_commands); false: the acceleration is a random walk only",
    )
    accel_command_cornering_drag: bool = setting(
        True, doc="the acceleration a command gives is the command plus the front tyres' "
        "lateral force along the car, -F_yf sin(delta) / m, at the estimate when it is told "
        "(estimation.process_model): in a turn the car slows by it",
    )
    accel_command_time_constant_s: float = setting(
        0.01, low=1e-3, high=2.0,
        doc="the lag of the car's acceleration behind its command, as the filter believes "
        "(the drive's and the tyres' response) [s]",
    )
    accel_commanded_jerk_psd_m2ps5: float = setting(
        0.00125, low=0.0, high=1e6,
        doc="the jerk's PSD once the filter is told acceleration commands, in place of "
        "jerk_psd_m2ps5 and jerk_relative_psd_1ps: what the drive does that its commands "
        "do not explain [m^2/s^5]",
    )
    accel_command_relative_sigma: float = setting(
        0.21, low=0.0, high=10.0,
        doc="standard deviation of the fraction of a command's change the car does not "
        "follow (the belief's mass and road loads, the tyres' transient)",
    )
    yaw_accel_psd_rad2ps3: float = setting(
        2.5e-4, low=0.0, high=1e6, doc="yaw acceleration the bicycle does not explain [rad^2/s^3]"
    )
    # A yaw kick (an unmeasured 5 deg heading step) is not process noise: it is handled by
    # ``inflate_on_surprise``. Raising this PSD to 5e-3 to follow the kick spoiled the circuit
    # (est. position RMSE 0.03 -> 0.21 m, NEES 31).
    # The three force-dependent terms below make the model's error grow where the physics
    # says it does (Pacejka, "Tyre and Vehicle Dynamics", 3rd ed. 2012, ch. 1: a tyre's force
    # is known to a fraction of itself; ch. 7: it lags the slip by the relaxation length):
    # set from 20-seed ensembles of the lane change on both sensor suites
    # (bench/estimator_consistency.py), where constant PSDs were under-confident on the
    # straights and over-confident in the swerves at the same time. Once the lateral
    # accelerometer's bias became a state (``ay_bias_mps2``, estimation.process_model), the constant
    # floors that had hidden it came down (heading 5e-7 -> 3e-8, lateral acceleration
    # 3e-4 -> 2e-5, residual sigma 0.02 -> 0.005, roll 1e-3 -> 3e-4, transient 1e-5 -> 1e-6).
    yaw_transient_psd_s3: float = setting(
        5e-7,
        low=0.0,
        high=1.0,
        doc="heading PSD per squared yaw acceleration of the bicycle: its yaw response is off "
        "while the yaw rate changes (tyre lag, compliance) [s^3]",
    )
    lateral_accel_psd_m2ps3: float = setting(
        1e-5, low=0.0, high=1e6, doc="white lateral acceleration driving vy_mps [m^2/s^3]"
    )
    yaw_moment_relative_psd_s: float = setting(
        0.0, low=0.0, high=10.0,
        doc="yaw acceleration PSD per squared yaw acceleration of each axle's moment: the "
        "axles' balance, and with it a turn's side slip, known to a fraction (0.3 on a "
        "circuit with rtk: docs/guide.md) [s]",
    )
    yaw_moment_load_transfer_psd_s5pm2: float = setting(
        0.0, low=0.0, high=100.0,
        doc="yaw acceleration PSD per squared product of the longitudinal acceleration and "
        "each axle's yaw acceleration: braking or driving in a turn shifts the axles' "
        "balance, and with it the side slip, by an amount known to a fraction [s^5/m^2]",
    )
    steer_psd_rad2ps: float = setting(
        5e-6,
        low=0.0,
        high=100.0,
        doc="white noise on the steering rate: steps the rate state does not follow",
    )
    steer_commanded_psd_rad2ps: float = setting(
        1.25e-6, low=0.0, high=100.0,
        doc="steer_psd_rad2ps once the filter is told steering commands: what the actuator "
        "does that its commands, its lag and the road wheels' gyroscopic deflection do not "
        "explain (estimation.steering_model) [rad^2/s]",
    )
    steer_commanded_timing_s: float = setting(
        0.002, low=0.0, high=1.0,
        doc="once told steering commands, how well the filter knows when the actuator moves "
        "(the plant's physics step: its wheels reach a step's end angle during the step): "
        "the steering's PSD grows by 2 timing^2 / tau per squared steering rate, tau the "
        "belief's steer_time_constant_s (estimation.process_model.ProcessNoise) [s]",
    )
    steer_rate_psd_rad2ps3: float = setting(
        0.025, low=0.0, high=1e4, doc="random walk of steer_rate_radps (steering acceleration)"
    )
    roll_accel_psd_rad2ps3: float = setting(
        1.5e-4, low=0.0, high=100.0, doc="roll acceleration the roll mode does not explain"
    )
    roll_accel_relative_psd_s: float = setting(
        5e-4,
        low=0.0,
        high=1.0,
        doc="roll-acceleration PSD per squared roll acceleration the tyres' lateral force "
        "commands (omega^2 G a_y): the roll mode's error grows with the force [s]",
    )
    # The elasticities of the sedan's MF 6.1 tyre's cornering stiffness in its load at the
    # static wheel loads (cosim.plant.tyre_model.cornering_stiffness_load_elasticity):
    # docs/defaults.md, "The axles' load transfer".
    tyre_load_sensitivity_front: float = setting(
        0.58, low=0.0, high=2.0,
        doc="exponent of the front axle's cornering stiffness in its load, which the "
        "longitudinal acceleration moves between the axles (estimation.bicycle, (D3''))",
    )
    tyre_load_sensitivity_rear: float = setting(
        0.74, low=0.0, high=2.0,
        doc="the same for the rear axle; both 0: the axle loads stay static",
    )
    # The sedan's MF 6.1 tyres' relaxation lengths K_ya / c_y at its static wheel loads
    # (cosim.plant.tyre_model.relaxation_lengths_m), each axle's stiffness scale applied:
    # docs/defaults.md, "The tyres' relaxation".
    tyre_relaxation_length_front_m: float = setting(
        0.235, low=0.0, high=2.0,
        doc="road the front tyres roll while their lateral force follows their slip angle "
        "(estimation.bicycle, (D3'''))",
    )
    tyre_relaxation_length_rear_m: float = setting(
        0.252, low=0.0, high=2.0,
        doc="the same for the rear tyres; both 0: the forces follow the slip angles at once",
    )
    # docs/defaults.md, "The wheels' lateral load transfer".
    lateral_load_transfer: bool = setting(
        True, doc="the front wheels' yaw moment t_f / 2 sin(delta) (F_yl - F_yr), their forces "
        "split by their loads as the roll moment m h a_y moves load outwards (estimation."
        "bicycle, (D3''''), (D5')); false: the axles' yaw moment alone (docs/defaults.md, "
        "\"The wheels' lateral load transfer\")",
    )
    # The sedan's steering servo gain (cosim.plant.sedan_model: k = I_d omega_s^2, the
    # wheel's diametral inertia 0.570 kg m^2 at 100 rad/s): docs/defaults.md, "The road
    # wheels' gyroscopic deflection".
    steering_compliance_radpnm: float = setting(
        1.0 / 5700.417, low=0.0, high=1.0,
        doc="each front wheel's deflection about its steering axis per newton metre (1 / the "
        "steering's stiffness): with the wheels' spin inertia the road wheels lag the "
        "actuator by I_s (v_x / R) p / k while the body rolls at p (estimation."
        "steering_model, (S4)); 0: rigid",
    )
    lateral_residual_sigma_mps2: float = setting(
        0.0035,
        low=1e-6,
        high=100.0,
        doc="stationary sigma of the lateral force the tyre model does not explain, per mass",
    )
    lateral_residual_relative: float = setting(
        0.035,
        low=0.0,
        high=1.0,
        doc="relative error of the tyre model's lateral force: the residual's stationary sigma "
        "is sqrt(sigma^2 + (this * a_y)^2) at the tyres' lateral acceleration a_y",
    )
    lateral_residual_time_constant_s: float = setting(
        0.5, low=0.05, high=1e4, doc="the lateral residual relaxes to zero with this time constant"
    )
    yaw_psd_rad2ps: float = setting(
        1.5e-8, low=0.0, high=10.0, doc="heading random walk (unmodelled yaw errors) [rad^2/s]"
    )
    position_psd_m2ps: float = setting(
        5e-7, low=0.0, high=100.0, doc="position random walk (unmodelled motion) [m^2/s]"
    )
    rolling_radius_scale_psd_1ps: float = setting(
        5e-7, low=0.0, high=1.0, doc="random walk of rolling_radius_scale (drive slip) [1/s]"
    )
    wheel_track_scale_psd_1ps: float = setting(
        5e-7, low=0.0, high=1.0, doc="random walk of wheel_track_scale (load, camber) [1/s]"
    )
    max_step_s: float = setting(
        0.01, low=1e-4, high=0.02, doc="longest sub-step of a prediction interval"
    )
    history_s: float = setting(
        0.0, low=0.0, high=2.0,
        doc="how far back a late measurement (sensors.gnss.latency_s) is fused at its own "
        "time, the filter's later steps re-run (estimation.history); 0: none, a measurement "
        "from before the filter's time is rejected as stale",
    )

    # Model errors of the measurement equations, added to each measurement's own covariance.
    wheel_model_sigma_mps: float = setting(
        0.002, low=0.0, high=10.0, doc="tyre slip, rolling-radius error (at the wheel centre)"
    )
    wheel_slip_per_force_ratio: float = setting(
        1.0 / 21.51, low=0.0, high=1.0,
        doc="wheel-speed model: longitudinal slip ratio per unit of F_x / F_z, the inverse of "
        "the tyre's slip stiffness per load (p_Kx1 = 21.51 of the plant's default tyre, "
        "Pacejka 2012); 0: the wheels roll without slip (estimation.wheel_slip)",
    )
    wheel_slip_combined_stiffness_1prad: float = setting(
        12.35, low=0.0, high=100.0,
        doc="wheel-speed model: the combined-slip weight's stiffness B, the slip of a force "
        "growing by sqrt(1 + (B alpha)^2) at the wheel's slip angle alpha (r_Bx1 = 12.35 of "
        "the plant's default tyre, Pacejka 2012); 0: none (estimation.wheel_slip)",
    )
    wheel_slip_peak_force_ratio: float = setting(
        1.0, low=0.05, high=1e3,
        doc="wheel-speed model: the tyre's peak longitudinal force per load, mu (1.0: the "
        "plant's default tyre on its default road); near it a force takes a growing slip, "
        "the Magic Formula's curve inverted (estimation.wheel_slip, (S1')); 1000: the slip "
        "proportional to the force",
    )
    wheel_slip_shape: float = setting(
        1.685, low=1.0, high=2.0,
        doc="wheel-speed model: the tyre's longitudinal shape factor C (p_Cx1 = 1.685 of the "
        "plant's default tyre, Pacejka 2012; estimation.wheel_slip, (S1'))",
    )
    wheel_slip_curvature: float = setting(
        0.344, low=-10.0, high=0.95,
        doc="wheel-speed model: the tyre's longitudinal curvature factor E (p_Ex1 = 0.344 of "
        "the plant's default tyre, Pacejka 2012; estimation.wheel_slip, (S1'))",
    )
    tyre_vertical_compliance_mpn: float = setting(
        0.0, low=0.0, high=1e-4,
        doc="wheel-speed model: the tyre's loaded radius drop per newton of vertical load, "
        "1 / k_z; the rolling radius is R s - F_z / k_z with F_z the wheel's load of the "
        "slip model (estimation.wheel_slip.wheel_load); 0: the radius does not move with load",
    )
    lateral_accel_model_sigma_mps2: float = setting(
        0.0, low=0.0, high=50.0,
        doc="IMU lateral acceleration: vibration, mounting (its bias is a state)",
    )
    steer_model_sigma_rad: float = setting(
        0.0, low=0.0, high=1.0, doc="steering sensor: mean road-wheel angle vs the bicycle's"
    )

    # Initial uncertainty (the mean comes from the scenario's initial state).
    init_position_sigma_m: float = setting(0.5, low=1e-6, high=1e4)
    init_yaw_sigma_rad: float = setting(
        0.01, low=1e-6, high=10.0, doc="the run starts at the scenario's initial state"
    )
    init_speed_sigma_mps: float = setting(0.5, low=1e-6, high=100.0)
    init_lateral_speed_sigma_mps: float = setting(0.1, low=1e-6, high=100.0)
    init_yaw_rate_sigma_radps: float = setting(0.05, low=1e-6, high=10.0)
    init_accel_sigma_mps2: float = setting(0.5, low=1e-6, high=100.0)
    init_steer_sigma_rad: float = setting(0.05, low=1e-6, high=1.0)
    init_steer_rate_sigma_radps: float = setting(0.05, low=1e-6, high=10.0)
    init_roll_sigma_rad: float = setting(0.005, low=1e-6, high=1.0)
    init_roll_rate_sigma_radps: float = setting(0.02, low=1e-6, high=10.0)
    init_gyro_bias_sigma_radps: float = setting(
        0.002, low=1e-9, high=1.0, doc="spread of the gyro's turn-on bias"
    )
    init_accel_bias_sigma_mps2: float = setting(
        0.02, low=1e-9, high=10.0, doc="spread of the accelerometers' turn-on bias (ax and ay)"
    )
    init_wheel_track_scale_sigma: float = setting(
        0.1, low=1e-6, high=0.5, doc="relative error of the believed track at the wheels"
    )
    init_rolling_radius_scale_sigma: float = setting(
        0.005, low=1e-6, high=0.5, doc="relative error of the believed wheel radius"
    )

    # Outlier rejection.
    gate: bool = setting(True, doc="reject updates whose NIS exceeds the chi-square gate")
    gate_imu: bool = setting(
        False,
        doc="gate the IMU too. Off: the IMU is the filter's one direct view of sudden motion "
        "(a yaw kick, a kerb strike), which the process model cannot predict; gated, a 5 deg "
        "heading step (the ``disturbances:`` heading kick) was rejected for gate_release_s and "
        "the car left the path by 1.1 m, against 0.09 m ungated",
    )
    inflate_on_surprise: bool = setting(
        True,
        doc="an ungated sensor (the IMU) far outside the gate is a manoeuvre the model did "
        "not predict: room is made in P along the process noise before it is fused. Off: "
        "a 5 deg yaw kick went into the gyro bias and the car left the path by 2.1 m",
    )
    gate_probability: float = setting(
        0.9999, low=0.5, high=0.999999999, doc="chi-square probability of the NIS gate"
    )
    gate_release_s: float = setting(
        2.0,
        low=0.0,
        high=1e9,
        doc="after a sensor's updates fail the gate for this long, fuse them ungated",
    )

    compiled: bool = setting(
        True,
        doc="evaluate the filter's models as C compiled with gcc instead of CasADi's virtual "
        "machine (ekf: the process model's sub-step, the measurement models and the joint "
        "update of an instant's measurements; ukf: the process noise, the sub-step of every "
        "sigma point and every measurement model at every sigma point; one library per "
        "filter, built once per machine with a note and cached under ~/.cache/cosim; the "
        "belief's numbers are its parameters, so one build serves every belief): the same "
        "estimates, the filter about 2x faster. Without a C compiler: the virtual machine, "
        "with a warning",
    )

    # Iterated update (ekf only): estimation.ekf.Ekf._joint_update.
    ekf_iterations: int = setting(
        5, low=0, high=50,
        doc="most relinearisations of an instant's update at its posterior (the iterated "
        "EKF); 0: the plain EKF, the models linearised at the prior mean only",
    )
    ekf_linearisation_tolerance: float = setting(
        0.1, low=0.0, high=1e3,
        doc="relinearise while the update's largest linearisation error exceeds this many "
        "standard deviations of the measurement noise",
    )

    # Unscented transform (ukf only): Van der Merwe's scaled sigma points.
    ukf_alpha: float = setting(1.0, low=1e-4, high=1.0, doc="spread of the sigma points")
    ukf_beta: float = setting(2.0, low=0.0, high=10.0, doc="prior knowledge of the distribution")
    ukf_kappa: float = setting(0.0, low=-10.0, high=10.0, doc="secondary scaling")

    def gates(self, sensor: str) -> bool:
        """Whether the NIS gate (``gate``, at ``gate_probability``) tests ``sensor``'s
        updates: every sensor's, the IMU's only with ``gate_imu``."""
        return self.gate and (sensor != "imu" or self.gate_imu)

    @property
    def tyre_load_sensitivities(self) -> tuple[float, float]:
        """``(front, rear)``: the exponents of (D3'') of :mod:`estimation.bicycle`."""
        return self.tyre_load_sensitivity_front, self.tyre_load_sensitivity_rear

    @property
    def tyre_relaxation_lengths_m(self) -> tuple[float, float]:
        """``(front, rear)``: the relaxation lengths of (D3''') of :mod:`estimation.bicycle`."""
        return self.tyre_relaxation_length_front_m, self.tyre_relaxation_length_rear_m


RESIDUAL_SIGMAS: tuple[str, ...] = ("lateral_residual_sigma_mps2", "lateral_residual_relative",
                                    "accel_command_relative_sigma")
"""The process noise given as sigmas: the lateral residual's stationary ones (a Gauss-Markov
process noise) and the drive's response to its commands."""
BIAS_WALKS: tuple[str, ...] = ("gyro_bias_walk_radps", "accel_bias_walk_mps2")
"""The IMU biases' random walks (``noise.*``, given per sqrt(s): sigmas)."""


def process_noise_fields() -> tuple[str, ...]:
    """Every process-noise PSD of :class:`EstimatorConfig` (the fields named ``*_psd_*``)."""
    return tuple(f.name for f in dataclasses.fields(EstimatorConfig) if "_psd_" in f.name)


def scaled_process_noise(config: EstimatorConfig, factor: float) -> EstimatorConfig:
    """``config`` with all its process noise times ``factor``: every PSD times ``factor``,
    every process-noise sigma (the lateral residual's, the bias walks) times
    ``sqrt(factor)``, so ``Q`` as a whole scales by ``factor``. A filter tuned right
    (``factor`` 1) against the same filter mistuned (0.3, 3) is what a consistency test
    must tell apart."""
    if not (math.isfinite(factor) and factor > 0.0):
        raise ValueError(f"factor = {factor!r}: expected a positive number")
    root = math.sqrt(factor)
    noise = dataclasses.replace(config.noise, **{
        name: root * getattr(config.noise, name) for name in BIAS_WALKS})
    return dataclasses.replace(
        config, noise=noise,
        **{name: factor * getattr(config, name) for name in process_noise_fields()},
        **{name: root * getattr(config, name) for name in RESIDUAL_SIGMAS})
