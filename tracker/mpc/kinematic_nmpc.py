"""Nonlinear MPC on the kinematic bicycle.

As in Kong, Pfeiffer, Schildbach, Borrelli, "Kinematic and dynamic vehicle models for
autonomous driving control design", IEEE Intelligent Vehicles Symposium 2015 (the model:
Rajamani, "Vehicle Dynamics and Control", 2nd ed., Springer 2012, sec. 2.2).

The shared NLP machinery (reference, cost, bounds, warm start, latency, fallback and safe
stop, plan) is :class:`tracker.mpc.nmpc.Nmpc`; this module supplies the model: the kinematic
bicycle at the centre of gravity, RK4 over one stage (:mod:`tracker.models.kinematic_bicycle`),
every state read from the estimate by name (the estimate's ``vx_mps`` stands for the
model's speed, the CoG speed; ``vy`` is not read).

The kinematic model has no steering actuator, so its ``unmodelled_lag_s`` is the belief's
steering time constant ``tracker.model.steer_time_constant_s``: the estimate is predicted
over it plus ``tracker.latency_s`` (the earlier fixed ``latency_s``, lag plus half a period,
did no better: docs/defaults.md).

``tracker.kinematic_understeer`` (the default) keeps the four states but turns at the
steady-state yaw rate and slip angle of the belief's linear tyres ((U1)-(U2) of
:mod:`tracker.models.kinematic_bicycle`). The pure kinematic model cannot track the
lane change on an understeering car (a kinematic MPC becomes unstable on an understeering
car: the car turns less than the model expects); with the steady-state understeer it can:
at 0.5 g the transient lateral dynamics settle within a few tenths of a second and the
steering lag is predicted over, so what the kinematic model lacked was the steady-state
gain (measured: docs/defaults.md, ``kinematic-nmpc``).
"""

from __future__ import annotations

from cosim.core.exceptions import ConfigError
from tracker.config import TrackerConfig
from tracker.models.kinematic_bicycle import (
    INPUT_NAMES,
    STATE_NAMES,
    discrete_function,
    predict_function,
)
from tracker.mpc.nmpc import Nmpc, NmpcModel

TRACKER_NAME = "kinematic-nmpc"
"""``tracker.name`` of this tracker."""


def kinematic_model(config: TrackerConfig) -> NmpcModel:
    """The kinematic bicycle (eqs. K1-K5, or U1-U2 with ``tracker.kinematic_understeer``)
    with the belief ``config.model``, as an NMPC model; every state comes from the
    estimate."""
    return NmpcModel(
        name="kinematic_nmpc",
        state_names=STATE_NAMES,
        input_names=INPUT_NAMES,
        estimated_state_names=STATE_NAMES,
        step=discrete_function(config.model, config.dt_s,
                               understeer=config.kinematic_understeer),
        predict=predict_function(config.model, understeer=config.kinematic_understeer),
        dt_s=config.dt_s,
        unmodelled_lag_s=config.model.steer_time_constant_s,
    )


class KinematicNmpc(Nmpc):
    """Kinematic-bicycle NMPC path tracker (Kong et al. 2015; ``tracker.solver``).

    Args:
      config: the tracker configuration; ``config.model`` is the controller's belief
        about the car (``cog_front_m``, ``cog_rear_m`` enter the kinematic model and
        ``steer_time_constant_s`` the prediction over the latency).
    """

    def __init__(self, config: TrackerConfig) -> None:
        if config.name != TRACKER_NAME:
            raise ConfigError(f"name = {config.name!r}: KinematicNmpc expects {TRACKER_NAME!r}")
        super().__init__(config, kinematic_model(config))
