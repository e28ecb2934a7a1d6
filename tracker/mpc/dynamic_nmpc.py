"""Nonlinear MPC on the linear-tyre dynamic bicycle with its steering actuator.

Why: on an understeering car the kinematic NMPC does not track the lane change: its
model puts the CoG velocity into the turn and expects the full kinematic yaw rate, while the
car yaws less and its velocity points out of the turn (a kinematic MPC becomes unstable on
an understeering car; a dynamic model is needed).

The model is the dynamic bicycle of Rajamani, "Vehicle Dynamics and Control", 2nd ed.,
Springer 2012, sec. 2.3, with the steering actuator as a state
(:mod:`tracker.models.steered_dynamic_bicycle`); the NLP, cost, bounds, warm start, latency,
fallback, safe stop and plan are the shared :class:`tracker.mpc.nmpc.Nmpc` (the tracking
NMPC). The belief is ``tracker.model``: mass, yaw inertia, CoG position, the axle cornering
stiffnesses (defaults from ``cosim identify``), the steering time constant and the friction.

Choices: the steering actuator is a first-order lag of the command (the runner holds one
command per control period and the plant lags it, which is exactly the model), its angle an
internal state propagated with the applied commands; ``vy`` and ``r`` come from the estimate;
both axles' slip angles are softly limited to the linear tyres' range
(``mu m g l_r / (L C_f)``, ``mu m g l_f / (L C_r)``) by a quadratic exterior penalty, not
slack variables. The measurements behind each choice: README, "Why the defaults",
``dynamic-nmpc``; today's accuracy: ``docs/trackers.md``.
"""

from __future__ import annotations

from cosim.core.exceptions import ConfigError
from tracker.config import TrackerConfig
from tracker.models.steered_dynamic_bicycle import (
    INPUT_NAMES,
    STATE_NAMES,
    VEHICLE_STATE_NAMES,
    SteeredBicycleParams,
    discrete_function,
    linear_range_slip_rad,
    predict_function,
    slip_angle_function,
)
from tracker.models.tyre_limits import LIMIT_NAMES, friction_usage_function, usage_bounds
from tracker.mpc.nmpc import Nmpc, NmpcModel

TRACKER_NAME = "dynamic-nmpc"
"""``tracker.name`` of this tracker."""


def dynamic_model(config: TrackerConfig) -> NmpcModel:
    """The steered dynamic bicycle with the belief ``config.model``, as an NMPC model.

    The six vehicle states are read from the estimate by name; the road-wheel angle is
    internal (no estimator needs to report it): the tracker propagates it with the
    commands it applied, through the belief's actuator lag. Soft limits keep both axles'
    slip angles within the linear tyres' range at the belief's friction
    (``model.tyre_friction``) and, with ``grip.tyre_limits``, each axle's combined force
    within its friction ellipse (:mod:`tracker.models.tyre_limits`).
    """
    params = SteeredBicycleParams.from_vehicle(config.model)
    tyre_limits = {}
    grip = config.grip
    if grip.tyre_limits and config.model.tyre_friction < grip.tyre_limits_below_friction:
        tyre_limits = {
            "stage_limits": friction_usage_function(config.model, params,
                                                    config.model.tyre_friction),
            "stage_limit_names": LIMIT_NAMES,
            "stage_limit_bounds": usage_bounds(config.grip.usage_max),
        }
    return NmpcModel(
        name="dynamic_nmpc",
        state_names=STATE_NAMES,
        input_names=INPUT_NAMES,
        estimated_state_names=VEHICLE_STATE_NAMES,
        step=discrete_function(params, config.dt_s),
        predict=predict_function(params),
        dt_s=config.dt_s,
        unmodelled_lag_s=0.0,
        understeer_gradient_radpmps2=params.bicycle.understeer_gradient_radpmps2,
        internal_rest_inputs={"road_wheel_angle_rad": "steer_rad"},
        limits=slip_angle_function(params),
        limit_names=("front_slip_rad", "rear_slip_rad"),
        limit_bounds=linear_range_slip_rad(params, config.model.tyre_friction),
        **tyre_limits,
    )


class DynamicNmpc(Nmpc):
    """Dynamic-bicycle NMPC path tracker (Rajamani 2012, sec. 2.3; ``tracker.solver``).

    Args:
      config: the tracker configuration; ``config.model`` is the controller's belief
        (mass, yaw inertia, CoG position, axle cornering stiffnesses, steering time
        constant, friction).

    The estimate must hold ``x_m, y_m, yaw_rad, vx_mps, vy_mps, yaw_rate_radps``. The
    plan's states are :data:`tracker.models.steered_dynamic_bicycle.STATE_NAMES`; its inputs
    are the commands.
    """

    def __init__(self, config: TrackerConfig) -> None:
        if config.name != TRACKER_NAME:
            raise ConfigError(f"name = {config.name!r}: DynamicNmpc expects {TRACKER_NAME!r}")
        super().__init__(config, dynamic_model(config))
