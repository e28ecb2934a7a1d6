"""Old spellings of configuration keys, still accepted: each names its key of today.

The keys are spelt one way, British (``tyre``, ``manoeuvre``, ``linearise``), and a tracker's
steering bound is one key, ``tracker.max_steer_rad``. A scenario, a ``--config`` file, a
``--set`` override or a sweep spec written with an older key still works: the key is moved
to its new name and one line says so (:class:`DeprecatedKeyWarning`; the command line prints
it as ``cosim: warning: ...``). Keys are a contract (scripts and outside tests set them), so
an old spelling is never silently dropped; giving a key under both names is an error.

An entry may name a whole section (``maneuver`` moves every key below it).
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from types import MappingProxyType
from typing import Any

from cosim.core.exceptions import ConfigError

KEY_ALIASES: Mapping[str, str] = MappingProxyType({
    "plant.tire_friction": "plant.tyre_friction",
    "plant.tire_model": "plant.tyre_model",
    "tracker.model.tire_friction": "tracker.model.tyre_friction",
    "tracker.ltv_mpc.linearize_about": "tracker.ltv_mpc.linearise_about",
    "tracker.dynamic_mpc.max_steer_rad": "tracker.max_steer_rad",
    "maneuver": "manoeuvre",
})
"""Old dotted key (or section) -> the key (or section) of today."""


REMOVED_KEYS: Mapping[str, str] = MappingProxyType({
    "lead_car": "the single lead car is gone; a traffic car does its job: write "
                "traffic: {lead: {gap_m: G, lateral_offset_m: Y, speed_profile: piecewise, "
                "speed_mps: V0, accel_profile: [{t_s: T, accel_mps2: A}]}} (docs/acc.md)",
})
"""Keys that no longer exist, each with what to write instead (refused, not moved: their
meaning has no one-to-one successor)."""


class DeprecatedKeyWarning(UserWarning):
    """A configuration key was given under an old name (:data:`KEY_ALIASES`)."""


def note(old: str, new: str, where: str = "") -> None:
    """Warn, in one line, that ``old`` (given in ``where``) is now ``new``."""
    place = f" ({where})" if where else ""
    warnings.warn(f"{old}{place} is an old spelling: it still works, but write {new}",
                  DeprecatedKeyWarning, stacklevel=3)


def canonical_key(key: str, where: str = "", warn: bool = True) -> str:
    """``key`` under its name of today (itself if it has no old spelling), with the note."""
    for old, new in KEY_ALIASES.items():
        if key == old or key.startswith(old + "."):
            renamed = new + key[len(old):]
            if warn:
                note(key, renamed, where)
            return renamed
    return key


def _section(data: dict[str, Any], path: list[str], create: bool) -> dict[str, Any] | None:
    """The nested mapping at ``path`` (created empty if asked), or None."""
    node: Any = data
    for part in path:
        child = node.get(part) if isinstance(node, dict) else None
        if child is None and create and isinstance(node, dict):
            child = node[part] = {}
        if not isinstance(child, dict):
            return None
        node = child
    return node


def rename_old_keys(data: dict[str, Any], where: str = "", warn: bool = True) -> dict[str, Any]:
    """Move every key of the nested mapping ``data`` given under an old name to its name of
    today, in place (and return ``data``); a key given under both names is a
    :class:`ConfigError`, and so is a removed key (:data:`REMOVED_KEYS`). ``where`` names
    the source in the note (a file, ``--config``)."""
    for removed, instead in REMOVED_KEYS.items():
        *path, leaf = removed.split(".")
        section = _section(data, path, create=False)
        if section is not None and leaf in section:
            raise ConfigError(f"{removed}{f' ({where})' if where else ''}: {instead}")
    for old, new in KEY_ALIASES.items():
        *old_path, old_leaf = old.split(".")
        source = _section(data, old_path, create=False)
        if source is None or old_leaf not in source:
            continue
        *new_path, new_leaf = new.split(".")
        target = _section(data, new_path, create=True)
        if target is None:
            continue  # the new section is not a mapping: from_dict names the bad value
        if new_leaf in target:
            raise ConfigError(f"{old} and {new}{f' ({where})' if where else ''}: the same "
                              f"key under its old and its new name: expected only {new}")
        target[new_leaf] = source.pop(old_leaf)
        if warn:
            note(old, new, where)
    return data
