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

Default tuning (measured on the MuJoCo sedan with the EKF in the loop, stretched double lane
change at 20 m/s from 15 m/s, about 0.5 g; the tracker tests check the kinematic bench):

* ``steer_rate`` dominates the steering terms. The kinematic model has neither the car's
  yaw and sideslip dynamics nor the steering actuator (50 ms first-order lag, 0.8 rad/s).
  A fast loop (``cte`` / ``steer_rate`` of 4, the first guess) diverged on the plant as
  soon as the steering lagged more than the model believed (120 ms lag, 100 ms delay, wet
  road). At a ratio of 0.5 the nominal car stays well within 0.1 m of the path, and within
  0.45 m with a 0.2 s steering lag. The other weights matter little: ``heading`` is small
  next to ``cte`` and only damps; ``speed`` against ``accel`` makes the car accelerate at
  the 3 m/s^2 bound from 15 to 20 m/s, as in the seed paper (section 2).
* ``latency_s = 0.075``: the 50 ms steering time constant of the default plant plus half
  of the 50 ms control period (zero-order hold). Predicting the estimate over it (section
  1, item (a)) lowers the nominal max CTE from about 0.14 m to 0.06-0.09 m, and with an
  extra 100 ms actuator delay in the plant from 1.8 m to 0.33 m. Set it to 0 for a plant
  that acts instantly (as the kinematic test bench does), and add
  ``plant.actuator_delay_s`` to it when the plant has a transport delay.
* ``horizon = 25`` at ``dt_s = 0.05``: 1.25 s or 25 m of preview at 20 m/s, the length of
  one steering swing of the lane change (section 1: longer horizons at higher speed). 20
  and 30 stages give within 10 % of the same errors.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from cosim.config_fields import section, setting
from cosim.exceptions import ConfigError
from cosim.vehicle_params import VehicleParams

TRACKER_CHOICES: tuple[str, ...] = ("kinematic-nmpc", "open-loop")
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
    steer_rate: float = setting(20.0, low=0.0, high=1e6, doc="(steering rate)^2 [s/rad^2]")


@dataclass(frozen=True)
class TrackerConfig:
    """A path tracker: which one, its horizon, cost, bounds, solver and internal model.

    ``model`` is the controller's belief about the car; the plant's truth lives in the
    ``plant`` section. Their difference is the model mismatch under study.
    """

    name: str = setting("kinematic-nmpc", choices=TRACKER_CHOICES, doc="tracker to build")
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
        0.075, low=0.0, high=2.0, doc="actuation latency to predict over (seed section 1)"
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
