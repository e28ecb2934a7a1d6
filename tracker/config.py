"""Configuration of a path tracker: the ``tracker:`` section of a scenario.

Every key is a validated :func:`cosim.core.config_fields.setting`, so a scenario file or the
command line (``--set tracker.horizon=30``, ``--set tracker.weights.cte=5``) is checked by
:func:`cosim.core.config_fields.from_dict` and a bad value names its dotted key.

The cost the weights enter (a tracking MPC cost: Rawlings, Mayne, Diehl 2017; Kong et al.
2015) is integrated over the horizon::

    J = sum_{k=1..N} dt [ w_cte cte_k^2 + w_heading epsi_k^2 + w_speed (v_k - v_ref)^2 ]
      + sum_{k=0..N-1} dt [ w_accel a_k^2 + w_steer (delta_k - delta_ff,k)^2
                            + w_accel_rate ((a_k - a_{k-1}) / dt)^2
                            + w_steer_rate ((delta_k - delta_{k-1}) / dt)^2 ]

with ``a_{-1}, delta_{-1}`` the previously applied command and ``delta_ff,k`` the
steady-state steering of the reference's curvature (``curvature_feedforward``; zero when
off). Each weight multiplies the square of an SI quantity per second of horizon, so changing
``dt_s`` or ``horizon`` does not rescale the balance between the terms.

Latency (``latency_compensation``): the estimate is predicted over ``latency_s`` (by
default ``plant.actuator_delay_s``, the command's transport delay, which no model contains)
with the commands already in the delay line (:mod:`tracker.mpc.delay_line`). The steering
actuator's lag is not latency: the dynamic model contains it, and the kinematic model,
which lacks it, adds ``model.steer_time_constant_s`` to the delay it predicts over
(:mod:`tracker.mpc.kinematic_nmpc`).

The defaults of the weights and settings were chosen by measurement, on the default
tracker ``dynamic-nmpc``; the measurements behind each: docs/defaults.md.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

from cosim.core.config_fields import mapping, section, setting
from cosim.core.exceptions import ConfigError
from cosim.core.plugins import entry_point_names, is_import_path
from cosim.core.vehicle_params import MAX_STEER_BOUND_RAD, VehicleParams
from tracker.baselines.config import BaselineConfig
from tracker.cruise.config import AccConfig
from tracker.fmu.config import FmuConfig, is_fmu_name
from tracker.mpc.dynamic_mpc_config import DynamicMpcConfig
from tracker.mpc.grip_config import GripConfig
from tracker.mpc.horizon_reference import REFERENCE_KINDS
from tracker.mpc.ltv_mpc_config import LtvMpcConfig

TRACKER_CHOICES: tuple[str, ...] = (
    "kinematic-nmpc", "dynamic-nmpc", "dynamic-mpc", "ltv-mpc", "open-loop",
    "pid", "stanley", "pure-pursuit", "lqr",
)
"""Values ``tracker.name`` accepts; :data:`tracker.registry.TRACKER_NAMES` maps each one."""


STEER_BOUND_RAD = math.pi / 8.0
"""The steering bound of every tracker unless ``tracker.max_steer_rad`` says otherwise."""

REFERENCE_DESIGN_STEER_BOUND_RAD = math.radians(15.0)
"""``dynamic-mpc``'s default steering bound, its reference design's (Wang 2009; module
docstring of :mod:`tracker.mpc.dynamic_mpc`)."""


def default_steer_bound_rad(name: str) -> float:
    """The steering bound of the tracker ``name`` when ``tracker.max_steer_rad`` is unset."""
    return REFERENCE_DESIGN_STEER_BOUND_RAD if name == "dynamic-mpc" else STEER_BOUND_RAD


STEER_RATE_WEIGHT = 3.0
"""``tracker.weights.steer_rate`` when it is unset [s/rad^2], but for the trackers on the
dynamic bicycle (:data:`DYNAMIC_MODEL_STEER_RATE_WEIGHT`): ``kinematic-nmpc``'s model lacks
the yaw and side-slip dynamics, and a faster wheel made it worse (docs/defaults.md)."""

DYNAMIC_MODEL_STEER_RATE_WEIGHT = 0.3
"""``tracker.weights.steer_rate`` of ``dynamic-nmpc`` and ``ltv-mpc`` (one model, one cost,
two solvers) when it is unset [s/rad^2]: their model carries the yaw, the side slip and the
steering actuator, so a faster wheel tracks closer; the caution
(``tracker.caution_lateral_sigma_m``) calms it while the estimate is unsure
(docs/defaults.md)."""


def default_steer_rate_weight(name: str) -> float:
    """``tracker.weights.steer_rate`` of the tracker ``name`` when it is unset."""
    if name in ("dynamic-nmpc", "ltv-mpc"):
        return DYNAMIC_MODEL_STEER_RATE_WEIGHT
    return STEER_RATE_WEIGHT


def own_defaults(name: str) -> dict[str, float]:
    """The keys (dotted, under ``tracker``) whose default follows the tracker ``name``, with
    its values: a run of another tracker that keeps them has not changed them."""
    return {"max_steer_rad": default_steer_bound_rad(name),
            "weights.steer_rate": default_steer_rate_weight(name)}


PLUGIN_GROUP = "cosim.trackers"
"""Entry-point group of trackers from other packages (:mod:`tracker.plugins.loading`)."""


def is_plugin_name(name: str) -> bool:
    """Whether ``name`` names a tracker class from outside cosim: an import path or a
    plug-in (not an FMU: ``fmu:ctrl.fmu`` has the form of an import path; not a built-in
    name, which :func:`tracker.registry.make_tracker` takes first even where a plug-in
    declares it too, so the installed entry points are read only for other names)."""
    if name in TRACKER_CHOICES or is_fmu_name(name):
        return False
    return is_import_path(name) or name in entry_point_names(PLUGIN_GROUP)


@dataclass(frozen=True)
class TrackerWeights:
    """Weights of the tracking cost, per second of horizon."""

    cte: float = setting(10.0, low=0.0, high=1e6, doc="cross-track error^2 [1/(m^2 s)]")
    heading: float = setting(2.0, low=0.0, high=1e6, doc="heading error^2 [1/(rad^2 s)]")
    speed: float = setting(1.0, low=0.0, high=1e6, doc="(speed - reference)^2 [s/m^2]")
    accel: float = setting(0.1, low=0.0, high=1e6, doc="acceleration^2 [s^3/m^2]")
    steer: float = setting(1.0, low=0.0, high=1e6, doc="steering angle^2 [1/(rad^2 s)]")
    accel_rate: float = setting(
        0.05, low=0.0, high=1e6, doc="(rate of acceleration)^2 [s^5/m^2]"
    )
    steer_rate: float | None = setting(
        None, low=0.0, high=1e6,
        doc="(steering rate)^2, while the estimate is sure (caution_lateral_sigma_m); "
        "unset: 0.3 for dynamic-nmpc and ltv-mpc, 3 for kinematic-nmpc [s/rad^2]",
    )
    limit_excess: float = setting(
        1e4,
        low=0.0,
        high=1e9,
        doc="(excess over the model's soft limits)^2; dynamic-nmpc: tyre slip angles beyond "
        "the linear range [1/(rad^2 s)]",
    )
    tyre_excess: float = setting(
        1e4,
        low=0.0,
        high=1e9,
        doc="dynamic-nmpc with grip.tyre_limits: (excess of an axle's squared friction usage "
        "over grip.usage_max^2)^2 [1/s]",
    )


@dataclass(frozen=True)
class TrackerConfig:
    """A path tracker: which one, its horizon, cost, bounds, solver and internal model.

    ``model`` is the controller's belief about the car; the plant's truth lives in the
    ``plant`` section. Their difference is the model mismatch under study.
    """

    name: str = setting(
        "dynamic-nmpc",
        doc="tracker to build: one of " + ", ".join(TRACKER_CHOICES) + "; or a tracker "
        "from outside cosim: an installed plug-in (entry point group cosim.trackers, "
        "`cosim trackers`) or an import path my_pkg.my_module:MyTracker (docs/plugins.md); "
        "or a co-simulation FMU, fmu:PATH.fmu (FMI 2 or 3; tracker.fmu, docs/fmu.md)",
    )
    params: dict[str, Any] = mapping(
        doc="a plug-in tracker's own settings, passed to it (validated by its Params schema "
        "if it declares one), e.g. --set tracker.params.lookahead_time_s=0.3",
    )
    step_budget_s: float = setting(
        1.0, low=1e-4, high=3600.0,
        doc="a plug-in or FMU tracker's step that takes longer (wall clock) ends the run",
    )
    horizon: int = setting(25, low=2, high=200, doc="number of stages N")
    dt_s: float = setting(0.05, low=0.005, high=1.0, doc="length of one stage [s]")
    weights: TrackerWeights = section(TrackerWeights)
    max_steer_rad: float | None = setting(
        None, low=0.01, high=MAX_STEER_BOUND_RAD,
        doc="the steering bound |delta| the tracker commands within, at most "
        "model.max_steer_rad; unset: pi/8 (22.5 deg), 15 deg for dynamic-mpc (its reference "
        "design) [rad]",
    )
    max_steer_rate_radps: float = setting(
        0.8, low=0.01, high=100.0, doc="steering rate bound, |d delta / dt|"
    )
    accel_min_mps2: float = setting(-3.0, low=-20.0, high=0.0, doc="strongest braking")
    accel_max_mps2: float = setting(3.0, low=0.0, high=20.0, doc="strongest acceleration")
    reference: str = setting(
        "spline",
        choices=REFERENCE_KINDS,
        doc="reference over the horizon (tracker.mpc.horizon_reference): spline, the path "
        "itself at the arc lengths to be covered; cubic-polynomial, a cubic "
        "fitted to the waypoints in the vehicle frame",
    )
    kinematic_understeer: bool = setting(
        True,
        doc="kinematic-nmpc: turn at the steady-state yaw rate and slip of the belief's "
        "linear tyres (tracker.models.kinematic_bicycle (U1)-(U2)) instead of the kinematic ones; "
        "false is the pure kinematic model (max CTE 0.80 m against 0.054 m on the sedan)",
    )
    curvature_feedforward: bool = setting(
        True,
        doc="NMPCs: penalise the steering's departure from the steady-state angle of the "
        "reference's curvature (atan(L kappa) + K v^2 kappa, K the model's understeer "
        "gradient) rather than from straight ahead",
    )
    solver: str = setting(
        "fatrop",
        choices=("ipopt", "fatrop", "sqp-rti"),
        doc="NLP solver of kinematic-nmpc and dynamic-nmpc (measured table in "
        "docs/defaults.md, 'The NMPC solvers'): fatrop (default: interior point over the "
        "stages, converged to tolerance every step; IPOPT's optimum 2-3x faster), ipopt "
        "(interior point, general sparse; the reference), sqp-rti (real-time iteration: "
        "rti_iterations Gauss-Newton SQP steps per control step from the shifted plan, "
        "one QP each; the solve 3-5x faster than fatrop's and the same max CTE on the "
        "lane change, but at the grip limit it lags: with friction 0.6 known to the "
        "tracker 3 of 5 seeds spin at 2 steps a control step, none with fatrop)",
    )
    rti_qp_solver: str = setting(
        "hpipm",
        choices=("hpipm", "qrqp", "osqp"),
        doc="QP back-end of solver sqp-rti: hpipm (Riccati interior point over the stages; "
        "fastest), qrqp (CasADi's sparse active set; 2-3x slower), osqp (ADMM at 1e-6; "
        "fast on the kinematic model, 8x slower on the dynamic one)",
    )
    rti_iterations: int = setting(
        1, low=1, high=100,
        doc="SQP iterations per step of solver sqp-rti from the shifted plan (exactly this "
        "many; from a cold guess, at the first step, after a reset or a non-finite plan, "
        "it iterates to tolerance, at most max_iterations, else the solve fails). 2 keeps "
        "every state and the steering of every plan along the lane change within 1e-4 of "
        "IPOPT's optimum, the acceleration within 3e-4 m/s^2 (1: 1.8e-4 m/s in the speed "
        "at the horizon's end)",
    )
    compiled: bool = setting(
        True,
        doc="solvers sqp-rti (with hpipm) and fatrop: evaluate as C compiled with gcc -O1 "
        "instead of CasADi's virtual machine (sqp-rti: the whole step, hpipm's call "
        "included); the same plans, the solve 2-4x faster. The belief and the weights "
        "are parameters, so one build (10-20 s, with a note) serves every belief and "
        "weighting of a model, horizon and stage length; cached per machine under "
        "~/.cache/cosim. Without a C compiler: the virtual machine, with a warning. "
        "ipopt and sqp-rti with qrqp or osqp always run in the virtual machine",
    )
    max_iterations: int = setting(
        100, low=1, high=10000,
        doc="iteration limit of solvers ipopt and fatrop, and of sqp-rti from a cold guess"
    )
    tolerance: float = setting(
        1e-4, low=1e-12, high=1.0,
        doc="convergence tolerance of solvers ipopt and fatrop; sqp-rti from a cold guess "
        "stops once no entry of a step exceeds it"
    )
    caution_lateral_sigma_m: float = setting(
        0.06, low=0.0, high=100.0,
        doc="the NMPCs and the LTV-MPC weigh the steering rate by 1 + sigma^2 / this^2, "
        "sigma the estimate's standard deviation across the car's heading: a calmer wheel "
        "while the estimate is unsure (the start, a receiver without RTK); 0: off [m]",
    )
    latency_compensation: bool = setting(
        True,
        doc="predict the estimate over latency_s with the commands in the delay line",
    )
    latency_s: float = setting(
        0.0,
        low=0.0,
        high=2.0,
        doc="the command transport delay the tracker believes in (the nominal car's: 0; "
        "`plant` tells it plant.actuator_delay_s). A model without the steering actuator adds "
        "model.steer_time_constant_s to the prediction itself",
    )
    fallback_time_s: float = setting(
        0.5, low=0.0, high=10.0, doc="how long to replay the last plan before a safe stop"
    )
    safe_stop_accel_mps2: float = setting(
        -2.0, low=-20.0, high=0.0, doc="deceleration of the safe stop"
    )
    model: VehicleParams = section(VehicleParams)
    dynamic_mpc: DynamicMpcConfig = section(DynamicMpcConfig)
    ltv_mpc: LtvMpcConfig = section(LtvMpcConfig)
    baseline: BaselineConfig = section(BaselineConfig)
    grip: GripConfig = section(GripConfig)
    fmu: FmuConfig = section(FmuConfig)
    """How an FMU tracker (``name: fmu:PATH.fmu``, :mod:`tracker.fmu`) is fed."""
    acc: AccConfig = section(AccConfig)
    """Adaptive cruise control (:mod:`tracker.cruise.law`): when enabled it sets the acceleration
    from the range sensor and this tracker only steers."""

    def __post_init__(self) -> None:
        if self.max_steer_rad is None:  # the tracker's own default (one key, one concept)
            object.__setattr__(self, "max_steer_rad", default_steer_bound_rad(self.name))
        if self.weights.steer_rate is None:  # likewise
            object.__setattr__(self, "weights", dataclasses.replace(
                self.weights, steer_rate=default_steer_rate_weight(self.name)))
        if (self.name not in TRACKER_CHOICES and not is_fmu_name(self.name)
                and not is_plugin_name(self.name)):
            raise ConfigError(
                f"name = {self.name!r}: expected one of {', '.join(TRACKER_CHOICES)}, an "
                "installed plug-in (cosim trackers), an import path module:Class or "
                "fmu:PATH.fmu"
            )
        if not self.accel_min_mps2 < self.accel_max_mps2:
            raise ConfigError(
                f"accel_min_mps2 = {self.accel_min_mps2}: expected less than "
                f"accel_max_mps2 = {self.accel_max_mps2}"
            )
        if self.max_steer_rad > self.model.max_steer_rad:
            raise ConfigError(
                f"max_steer_rad = {self.max_steer_rad}: expected at most the model's "
                f"model.max_steer_rad = {self.model.max_steer_rad}"
            )
        if self.safe_stop_accel_mps2 < self.accel_min_mps2:
            raise ConfigError(
                f"safe_stop_accel_mps2 = {self.safe_stop_accel_mps2}: expected at least "
                f"accel_min_mps2 = {self.accel_min_mps2}"
            )

    @property
    def horizon_s(self) -> float:
        """Length of the prediction horizon, ``horizon * dt_s`` [s]."""
        return self.horizon * self.dt_s
