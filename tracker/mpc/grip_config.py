"""Settings of the NMPCs' friction awareness: the ``tracker.grip`` section.

Two mechanisms, both read the belief's friction ``tracker.model.tyre_friction``:

* ``tyre_limits`` (``dynamic-nmpc``): a soft friction-ellipse constraint per axle in the
  NLP (:mod:`tracker.models.tyre_limits`): the combined longitudinal and lateral force the plan
  asks of an axle stays within ``usage_max`` of ``mu F_z``, the load moved by the planned
  acceleration. Added only when the believed friction is below
  ``tyre_limits_below_friction`` (0.9): on the dry lane change it never binds (the
  3 m/s^2 acceleration bound uses 67 % of the rear axle's grip at friction 1.0) and it
  made the default run's solve about 15 % slower (bench, same iterations); the soft slip
  limits keep guarding the dry limit cases as before.
* ``speed_planning`` (``dynamic-nmpc`` and ``kinematic-nmpc``): the reference speed over
  the horizon is capped by the speed at which the path ahead can be driven with
  ``usage_max`` of the friction, braking at ``brake_usage`` of ``mu g`` to get there
  (:mod:`tracker.mpc.grip_speed`); the plan reports ``speed_reduced`` when the cap bites.

On the default lane change (friction 1.0, 0.5 g) neither binds; they matter on a wet road
(measurements in :mod:`tracker.models.tyre_limits`).
"""

from __future__ import annotations

from dataclasses import dataclass

from cosim.core.config_fields import setting


@dataclass(frozen=True)
class GripConfig:
    """How an NMPC keeps its plan within the tyres' believed friction."""

    tyre_limits: bool = setting(
        True,
        doc="dynamic-nmpc: soft friction ellipse per axle (combined longitudinal and lateral "
        "force of the plan within usage_max of mu F_z, load transfer by the planned "
        "acceleration included)",
    )
    tyre_limits_below_friction: float = setting(
        0.9,
        low=0.0,
        high=2.5,
        doc="tyre_limits only when the believed friction (tracker.model.tyre_friction) is "
        "below this: on a dry road they do not bind on the lane change and cost about 15 % "
        "solve time; 2.5: at any friction [-]",
    )
    saturating_tyres: bool = setting(
        True,
        doc="dynamic-nmpc: the model's axle forces saturate at the believed friction, "
        "mu F_z tanh(C alpha / (mu F_z)), instead of growing without bound with the slip "
        "angle (linear tyres promise more than the road gives near the limit)",
    )
    speed_planning: bool = setting(
        True,
        doc="NMPCs: cap the reference speed over the horizon by the friction-limited speed "
        "of the path ahead (slow down before a bend the tyres cannot hold at speed); the "
        "plan reports speed_reduced",
    )
    usage_max: float = setting(
        0.85,
        low=0.1,
        high=1.0,
        doc="share of the believed friction mu F_z a plan may use (tyre limits and the "
        "cornering speed of speed planning) [-]",
    )
    brake_usage: float = setting(
        0.4,
        low=0.05,
        high=1.0,
        doc="speed planning: deceleration towards a lower cornering speed, as a share of "
        "mu g [-]",
    )
    lookahead_s: float = setting(
        6.0,
        low=0.5,
        high=60.0,
        doc="speed planning: how far ahead the path is searched for bends, in seconds at "
        "the current speed (at least the braking distance is searched) [s]",
    )
