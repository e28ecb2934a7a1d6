"""Settings that the run will not read: a warning naming who does read them.

The configuration is one record for every tracker and plant variant (a sweep may vary a key
across trackers), so such a key is accepted, but silently ignoring it would let a user
believe a change was made: ``--tracker dynamic-mpc --set tracker.horizon=80`` changes
nothing (that MPC's horizon is ``tracker.dynamic_mpc.prediction_horizon``). Who reads which
``tracker.*`` key is :mod:`tracker.key_readers`; the plant reads its Magic Formula settings
only with ``plant.tyre_model = pacejka``.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from cosim.core.yaml_io import shown
from cosim.simulation.path_config import (
    PATH_KINDS,
    SPEED_PROFILES,
    PathConfig,
    path_keys_read,
)
from tracker.key_readers import PLUGIN_KEYS, is_read_by, readers

PACEJKA_ONLY_PLANT_KEYS = ("tyre", "front_cornering_stiffness_scale",
                           "rear_cornering_stiffness_scale")
"""``plant.*`` keys (or sections) the plant reads only with its Magic Formula tyres."""


class UnreadKeyWarning(UserWarning):
    """A configuration key that the chosen tracker or plant does not read."""


def _leaves(data: Any, prefix: str = "") -> Iterator[tuple[str, Any]]:
    if isinstance(data, dict) and data:
        for key, value in data.items():
            yield from _leaves(value, f"{prefix}.{key}" if prefix else str(key))
    elif prefix:
        yield prefix, data


def _default(defaults: dict[str, Any] | None, dotted: str) -> Any:
    node: Any = defaults
    for part in dotted.split("."):
        if not isinstance(node, dict) or part not in node:
            return _NO_DEFAULT
        node = node[part]
    return node


_NO_DEFAULT = object()


def unread_key_warnings(data: dict[str, Any], tracker_name: str, tyre_model: str,
                        speed_from_profile: bool = False,
                        defaults: dict[str, Any] | None = None) -> list[str]:
    """One line per key of the raw configuration ``data`` (scenario, ``--config`` and
    ``--set`` merged) that the tracker ``tracker_name``, the plant (``tyre_model``) or the
    start (``initial.speed_from_profile``) will not read, naming who does. A key at its
    value in ``defaults`` (the configuration's defaults, as plain dictionaries) changes
    nothing either way and is not reported: a whole configuration written by ``cosim config
    show`` runs without a warning per key."""
    lines = []
    initial = data.get("initial")
    if (speed_from_profile and isinstance(initial, dict) and "speed_mps" in initial
            and initial["speed_mps"] != _default(defaults, "initial.speed_mps")):
        lines.append(f"initial.speed_mps = {shown(initial['speed_mps'])} is not read with "
                     "initial.speed_from_profile = true: the car starts at the profile's "
                     "speed (set initial.speed_from_profile=false to choose it)")
    tracker = data.get("tracker")
    for key, value in _leaves(tracker if isinstance(tracker, dict) else {}):
        if is_read_by(tracker_name, key) or value == _default(defaults, f"tracker.{key}"):
            continue
        who = readers(key)
        what = ("plug-in trackers" if key.split(".")[0] in PLUGIN_KEYS
                else "tracker " + ", ".join(who))
        lines.append(f"tracker.{key} = {shown(value)} is not read by tracker "
                     f"{tracker_name}: it is read by {what}")
    plant = data.get("plant")
    if tyre_model != "pacejka" and isinstance(plant, dict):
        for key, value in _leaves(plant):
            if value == _default(defaults, f"plant.{key}"):
                continue
            if key.split(".")[0] in PACEJKA_ONLY_PLANT_KEYS:
                lines.append(f"plant.{key} = {shown(value)} is not read with plant.tyre_model "
                             f"= {tyre_model}: the plant reads it with plant.tyre_model = "
                             "pacejka")
    lines += _unread_path_keys(data.get("path"), defaults)
    return lines


def _unread_path_keys(path: Any, defaults: dict[str, Any] | None) -> list[str]:
    """``path.*`` keys the path's kind and speed profile do not read (``path.seed`` on a
    ``track``), at a value other than their default."""
    if not isinstance(path, dict):
        return []
    kind = path.get("kind", PathConfig.kind)
    profile = path.get("speed_profile", PathConfig.speed_profile)
    if kind not in PATH_KINDS or profile not in SPEED_PROFILES:
        return []  # from_dict names the bad value
    read = path_keys_read(str(kind), str(profile))
    lines = []
    for key, value in path.items():
        if key in read or value == _default(defaults, f"path.{key}"):
            continue
        who = [k for k in PATH_KINDS if key in path_keys_read(k, "constant")]
        profiles = [p for p in SPEED_PROFILES if key in path_keys_read("straight", p)]
        readers_text = (f"path.kind {', '.join(who)}" if who else
                        f"path.speed_profile {', '.join(profiles)}" if profiles else "no path")
        lines.append(f"path.{key} = {shown(value)} is not read by path.kind {kind} with "
                     f"path.speed_profile {profile}: it is read by {readers_text}")
    return lines
