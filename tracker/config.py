"""Configuration of a path tracker: the ``tracker:`` section of a scenario.

Every key is a validated :func:`cosim.config_fields.setting`, so a scenario file or the
command line (``--set tracker.horizon=30``, ``--set tracker.weights.cte=5``) is checked by
:func:`cosim.config_fields.from_dict` and a bad value names its dotted key.

The cost the weights enter (seed digest section 1) is integrated over the horizon::

    J = sum_{k=1..N} dt [ w_cte cte_k^2 + w_heading epsi_k^2 + w_speed (v_k - v_ref)^2 ]
      + sum_{k=0..N-1} dt [ w_accel a_k^2 + w_steer delta_k^2
                            + w_accel_rate ((a_k - a_{k-1}) / dt)^2
                            + w_steer_rate ((delta_k - delta_{k-1}) / dt)^2 ]

with ``a_{-1}, delta_{-1}`` the previously applied command. Each weight multiplies the
square of an SI quantity per second of horizon, so changing ``dt_s`` or ``horizon`` does not
rescale the balance between the terms.

Default tuning, shared by both NMPCs and made for the default tracker ``dynamic-nmpc``
(measured on the MuJoCo sedan with Pacejka tyres and the EKF in the loop, stretched double
lane change at 20 m/s from 15 m/s, about 0.5 g; max CTE for seeds 0/1/2, ``plant.mass_kg=
2000``, ``plant.tire_friction=0.7``; details in :mod:`tracker.dynamic_nmpc`):

* ``steer_rate = 3`` against ``cte = 10``. The dynamic model carries the yaw and sideslip
  dynamics and the steering actuator, so the loop can be much faster than the kinematic
  NMPC's ``steer_rate = 20`` (0.13 m nominal): ``steer_rate`` 1 / 3 / 10 gives
  0.050 / 0.056 / 0.096 m nominal, 0.094 / 0.110 / 0.157 m with the 2000 kg car. Below 3
  the gain is a few millimetres, bought with a jumpier wheel on the straight (RMS steering
  rate from sensor noise 0.048 / 0.032 / 0.020 rad/s) and less margin: with MuJoCo contact
  tyres (a car with no cornering compliance, far from the belief) ``steer_rate = 1``
  oscillated to 1.96 m, 3 gives 0.37 m (seed lesson: with noisy sensing, moderate weights
  beat aggressive ones). The kinematic NMPC with these weights: 0.75 m on the default
  sedan (1.56 m with 20); with contact tyres 0.12 m with the filter that has no tyre model
  (0.13 m with 20), 3.0 m with the filter that assumes the belief's linear tyres (0.69 m
  with 20): ``--set tracker.weights.steer_rate=20`` restores its earlier tuning.
  The other weights matter little: ``heading`` 0.5 instead of 2 changes nothing; ``speed``
  against ``accel`` makes the car accelerate at the 3 m/s^2 bound from 15 to 20 m/s, as in
  the seed paper (section 2).
* ``limit_excess = 1e4``: the soft limit on the dynamic model's slip angles (the linear
  tyres' range). It never binds at 0.5 g; on Falcone's unstretched path (1.11 g,
  ``lane-change-limit``) it keeps the car from spinning (0.70 m instead of 15.7 m).
* ``latency_s = 0``: the command's transport delay, which no model contains; set it to
  ``plant.actuator_delay_s`` (with a 100 ms delay: 0.12 m with ``latency_s = 0.1``,
  0.6-1.4 m without). The steering actuator's lag is not latency: the dynamic model
  contains it, and the kinematic model, which lacks it, adds ``model.steer_time_constant_s``
  itself (section 1, latency item (a); see :mod:`tracker.kinematic_nmpc`).
* ``horizon = 25`` at ``dt_s = 0.05``: 1.25 s or 25 m of preview at 20 m/s, the length of
  one steering swing of the lane change (section 1: longer horizons at higher speed). 20
  stages: 0.094 m; 30 stages: 0.052 m at about 15 % more solve time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from cosim.config_fields import section, setting
from cosim.exceptions import ConfigError
from cosim.vehicle_params import VehicleParams

TRACKER_CHOICES: tuple[str, ...] = ("kinematic-nmpc", "dynamic-nmpc", "open-loop")
"""Values ``tracker.name`` accepts; :data:`tracker.registry.TRACKER_NAMES` maps each one."""


@dataclass(frozen=True)
class TrackerWeights:
    """Weights of the tracking cost (seed digest section 1), per second of horizon."""

    cte: float = setting(10.0, low=0.0, high=1e6, doc="cross-track error^2 [1/(m^2 s)]")
    heading: float = setting(2.0, low=0.0, high=1e6, doc="heading error^2 [1/(rad^2 s)]")
    speed: float = setting(1.0, low=0.0, high=1e6, doc="(speed - reference)^2 [s/m^2]")
    accel: float = setting(0.1, low=0.0, high=1e6, doc="acceleration^2 [s^3/m^2]")
    steer: float = setting(1.0, low=0.0, high=1e6, doc="steering angle^2 [1/(rad^2 s)]")
    accel_rate: float = setting(
        0.05, low=0.0, high=1e6, doc="(rate of acceleration)^2 [s^5/m^2]"
    )
    steer_rate: float = setting(3.0, low=0.0, high=1e6, doc="(steering rate)^2 [s/rad^2]")
    limit_excess: float = setting(
        1e4,
        low=0.0,
        high=1e9,
        doc="(excess over the model's soft limits)^2; dynamic-nmpc: tyre slip angles beyond "
        "the linear range [1/(rad^2 s)]",
    )


@dataclass(frozen=True)
class TrackerConfig:
    """A path tracker: which one, its horizon, cost, bounds, solver and internal model.

    ``model`` is the controller's belief about the car; the plant's truth lives in the
    ``plant`` section. Their difference is the model mismatch under study.
    """

    name: str = setting("dynamic-nmpc", choices=TRACKER_CHOICES, doc="tracker to build")
    horizon: int = setting(25, low=2, high=200, doc="number of stages N")
    dt_s: float = setting(0.05, low=0.005, high=1.0, doc="length of one stage [s]")
    weights: TrackerWeights = section(TrackerWeights)
    max_steer_rad: float = setting(
        math.pi / 8.0, low=0.01, high=1.0, doc="steering bound, |delta| (seed section 1)"
    )
    max_steer_rate_radps: float = setting(
        0.8, low=0.01, high=100.0, doc="steering rate bound, |d delta / dt|"
    )
    accel_min_mps2: float = setting(-3.0, low=-20.0, high=0.0, doc="strongest braking")
    accel_max_mps2: float = setting(3.0, low=0.0, high=20.0, doc="strongest acceleration")
    max_iterations: int = setting(100, low=1, high=10000, doc="IPOPT iteration limit")
    tolerance: float = setting(1e-6, low=1e-12, high=1.0, doc="IPOPT convergence tolerance")
    latency_s: float = setting(
        0.0,
        low=0.0,
        high=2.0,
        doc="command transport delay to predict over (seed section 1), e.g. "
        "plant.actuator_delay_s; a model without the steering actuator adds "
        "model.steer_time_constant_s itself",
    )
    fallback_time_s: float = setting(
        0.5, low=0.0, high=10.0, doc="how long to replay the last plan before a safe stop"
    )
    safe_stop_accel_mps2: float = setting(
        -2.0, low=-20.0, high=0.0, doc="deceleration of the safe stop"
    )
    model: VehicleParams = section(VehicleParams)

    def __post_init__(self) -> None:
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
