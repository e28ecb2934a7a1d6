"""Which built-in tracker reads which key of the ``tracker:`` section.

The section is one record for every tracker (a sweep may vary a key across trackers), so a
key the chosen tracker does not read is accepted; :func:`readers` says who does, and
:func:`cosim.simulation.unread_keys.unread_key_warnings` warns with it
(``--tracker dynamic-mpc --set tracker.horizon=80``: ``dynamic-mpc`` predicts over
``tracker.dynamic_mpc.prediction_horizon``).

A key is named by its first component, or by its first two under ``baseline`` (each
baseline reads ``baseline.speed`` and its own law's section) and ``grip`` (both NMPCs plan
their speed by the grip; only ``dynamic-nmpc`` has the friction ellipse and the saturating
tyres). ``acc`` is read by whichever
tracker ``tracker.acc.enabled`` wraps; ``params`` and ``step_budget_s`` by plug-ins; a
plug-in may read any key, so none is reported for one.
"""

from __future__ import annotations

from types import MappingProxyType

_EVERY_TRACKER = frozenset({"name", "model", "acc", "latency_compensation", "latency_s"})
_BOUNDS = frozenset({"max_steer_rad", "max_steer_rate_radps", "accel_min_mps2",
                     "accel_max_mps2", "safe_stop_accel_mps2", "dt_s"})
_MPC = _EVERY_TRACKER | _BOUNDS | {"fallback_time_s"}
_SPEED_PLANNING = frozenset({"grip.speed_planning", "grip.usage_max", "grip.brake_usage",
                             "grip.lookahead_s"})
_NMPC = _MPC | _SPEED_PLANNING | {
    "horizon", "weights", "reference", "curvature_feedforward", "solver", "rti_qp_solver",
    "rti_iterations", "compiled", "max_iterations", "tolerance"}
_BASELINE = _EVERY_TRACKER | _BOUNDS | {"baseline.speed"}

KEYS_READ: MappingProxyType[str, frozenset[str]] = MappingProxyType({
    "kinematic-nmpc": _NMPC | {"kinematic_understeer"},
    "dynamic-nmpc": _NMPC | {"grip.tyre_limits", "grip.tyre_limits_below_friction",
                             "grip.saturating_tyres"},
    "ltv-mpc": _MPC | {"horizon", "weights", "reference", "ltv_mpc"},
    "dynamic-mpc": _MPC | {"dynamic_mpc"},
    "pid": _BASELINE | {"baseline.pid"},
    "stanley": _BASELINE | {"baseline.stanley"},
    "pure-pursuit": _BASELINE | {"baseline.pure_pursuit"},
    "lqr": _BASELINE | {"baseline.lqr"},
    "open-loop": _EVERY_TRACKER,
})
"""Per built-in tracker, the keys (module docstring) it reads."""

PLUGIN_KEYS = frozenset({"params", "step_budget_s"})
"""Keys only plug-in trackers read."""


def reader_key(dotted: str) -> str:
    """The key of :data:`KEYS_READ` a dotted key under ``tracker.`` belongs to
    (``weights.cte`` -> ``weights``, ``baseline.lqr.q_cte`` -> ``baseline.lqr``,
    ``grip.usage_max`` -> ``grip.usage_max``)."""
    parts = dotted.split(".")
    two_level = parts[0] in ("baseline", "grip") and len(parts) > 1
    return ".".join(parts[:2]) if two_level else parts[0]


def readers(dotted: str) -> tuple[str, ...]:
    """The built-in trackers that read ``tracker.<dotted>`` (plug-ins: :data:`PLUGIN_KEYS`)."""
    key = reader_key(dotted)
    return tuple(name for name, keys in KEYS_READ.items() if key in keys)


def is_read_by(name: str, dotted: str) -> bool:
    """Whether the tracker ``name`` reads ``tracker.<dotted>`` (True for a plug-in, which
    may read anything, and for a key no built-in tracker knows)."""
    keys = KEYS_READ.get(name)
    if keys is None:
        return True
    key = reader_key(dotted)
    return key in keys or (key not in PLUGIN_KEYS and not readers(dotted))
