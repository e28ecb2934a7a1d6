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
slack variables. The measurements behind each choice: docs/defaults.md,
``dynamic-nmpc``; today's accuracy: ``docs/trackers.md``.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from cosim.core.built_once import built_once
from cosim.core.exceptions import ConfigError
from cosim.core.vehicle_params import VehicleParams
from tracker.config import GripConfig, TrackerConfig
from tracker.models import dynamic_bicycle as bicycle
from tracker.models.steered_dynamic_bicycle import (
    BELIEF_NAMES,
    INPUT_NAMES,
    STATE_NAMES,
    VEHICLE_STATE_NAMES,
    ModelNumbers,
    SteeredBicycleParams,
    belief_discrete_function,
    belief_vector,
    discrete_function,
    linear_range_of,
    linear_range_slip_rad,
    predict_function,
    slip_angle_function,
    slip_angles_of,
)
from tracker.models.tyre_limits import (
    LIMIT_NAMES,
    USAGE_BELIEF_NAMES,
    friction_usage,
    friction_usage_function,
    usage_belief_vector,
    usage_bounds,
)
from tracker.mpc.nmpc import Nmpc, NmpcModel

TRACKER_NAME = "dynamic-nmpc"
"""``tracker.name`` of this tracker."""

NLP_BELIEF_NAMES: tuple[str, ...] = BELIEF_NAMES + USAGE_BELIEF_NAMES + ("usage_max",)
"""The belief as the NLP takes it, one parameter each: the steered bicycle's numbers
(:data:`tracker.models.steered_dynamic_bicycle.BELIEF_NAMES`, the friction among them, which
also bounds the slip angles and the friction ellipse), the ellipse's others
(:data:`tracker.models.tyre_limits.USAGE_BELIEF_NAMES`) and ``grip.usage_max``."""


def _belief_functions(model: VehicleParams, dt_s: float, grip: GripConfig,
                      params: SteeredBicycleParams, tyre_limits: bool) -> dict[str, object]:
    """The model's NLP functions with the belief :data:`NLP_BELIEF_NAMES` as an input, and
    its numbers for ``config``: one NLP for every belief of the same shape (whether the
    actuator lags, whether the tyres saturate, whether the friction ellipse is on, the RK4
    substeps)."""
    n_steered, n_bicycle = len(BELIEF_NAMES), len(bicycle.PARAM_NAMES)
    n_usage = len(USAGE_BELIEF_NAMES)
    numbers = np.concatenate((belief_vector(params),
                              usage_belief_vector(model),
                              [grip.usage_max]))
    state = ca.SX.sym("state", len(STATE_NAMES))
    inputs = ca.SX.sym("inputs", len(INPUT_NAMES))
    belief = ca.SX.sym("belief", len(NLP_BELIEF_NAMES))
    steered, usage = belief[:n_steered], belief[n_steered:n_steered + n_usage]
    friction = steered[BELIEF_NAMES.index("tyre_friction")]
    usage_max = belief[NLP_BELIEF_NAMES.index("usage_max")]
    step = belief_discrete_function(params, dt_s)
    slip = slip_angles_of(state, ModelNumbers.symbolic(steered, params))
    slip_bounds = ca.vertcat(*linear_range_of(steered[:n_bicycle], friction))
    functions: dict[str, object] = {
        "belief": tuple(float(v) for v in numbers),
        "belief_step": ca.Function("dynamic_nmpc_step", [state, inputs, belief],
                                   [step(state, inputs, steered)]),
        "belief_limits": ca.Function("dynamic_nmpc_slip", [state, belief],
                                     [slip, slip_bounds]),
    }
    if tyre_limits:
        g = friction_usage(state, inputs, steered[:n_bicycle], usage, friction,
                           params.low_speed_mps)
        functions["belief_stage_limits"] = ca.Function(
            "dynamic_nmpc_usage", [state, inputs, belief],
            [g, ca.vertcat(usage_max**2, usage_max**2)])
    return functions


def dynamic_model(config: TrackerConfig) -> NmpcModel:
    """The steered dynamic bicycle with the belief ``config.model``, as an NMPC model.

    The six vehicle states are read from the estimate by name; the road-wheel angle is
    internal (no estimator needs to report it): the tracker propagates it with the
    commands it applied, through the belief's actuator lag. With ``grip.saturating_tyres``
    the axle forces saturate at the belief's friction (``model.tyre_friction``), (D3') of
    :mod:`tracker.models.dynamic_bicycle`. Soft limits keep both axles' slip angles within
    the linear tyres' range at that friction and, with ``grip.tyre_limits``, each axle's
    combined force within its friction ellipse (:mod:`tracker.models.tyre_limits`). The
    model's functions are built once per process for the same belief, stage and grip
    settings.
    """
    return _dynamic_model(config.model, float(config.dt_s), config.grip)


@built_once
def _dynamic_model(belief: VehicleParams, dt_s: float, grip: GripConfig) -> NmpcModel:
    """:func:`dynamic_model` of ``tracker.model``, ``tracker.dt_s`` and ``tracker.grip``."""
    params = SteeredBicycleParams.from_vehicle(belief, saturating=grip.saturating_tyres)
    tyre_limits = {}
    if grip.tyre_limits and belief.tyre_friction < grip.tyre_limits_below_friction:
        tyre_limits = {
            "stage_limits": friction_usage_function(belief, params,
                                                    belief.tyre_friction),
            "stage_limit_names": LIMIT_NAMES,
            "stage_limit_bounds": usage_bounds(grip.usage_max),
        }
    return NmpcModel(
        name="dynamic_nmpc",
        state_names=STATE_NAMES,
        input_names=INPUT_NAMES,
        estimated_state_names=VEHICLE_STATE_NAMES,
        step=discrete_function(params, dt_s),
        predict=predict_function(params),
        dt_s=dt_s,
        unmodelled_lag_s=0.0,
        understeer_gradient_radpmps2=params.bicycle.understeer_gradient_radpmps2,
        steady_grip_mps2=(belief.tyre_friction * bicycle.GRAVITY_MPS2
                          if params.saturating else None),
        internal_rest_inputs={"road_wheel_angle_rad": "steer_rad"},
        limits=slip_angle_function(params),
        limit_names=("front_slip_rad", "rear_slip_rad"),
        limit_bounds=linear_range_slip_rad(params, belief.tyre_friction),
        **tyre_limits,
        **_belief_functions(belief, dt_s, grip, params, bool(tyre_limits)),
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
