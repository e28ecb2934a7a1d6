"""Default names of run logs: the scenario, a short tag of what was overridden, the time.

``cosim run lane-change --set plant.mass_kg=2000 --tracker ltv-mpc`` writes
``logs/lane-change-mass2000-ltv-mpc-20261201-170301.mcap``: a user listing ``logs/`` sees
what each run changed. The tag is deterministic (the same overrides give the same tag),
short (long tags are cut and end in a hash of the whole) and safe in any file system
(letters, digits, ``.``, ``+`` and ``-`` only).
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Sequence

from cosim.core.config_fields import UNIT_SUFFIXES

MAX_TAG_CHARS = 40
"""A longer tag keeps its first characters and ends in a hash of the whole."""
_UNSAFE = re.compile(r"[^A-Za-z0-9.+-]+")


def _safe(text: str) -> str:
    """``text`` as part of a file name: underscores and the separators of an import path
    (``my_pkg.mod:Tracker``) become hyphens, anything else unsafe is dropped."""
    return _UNSAFE.sub("", text.replace("_", "-").replace(":", "-"))


def _key_part(dotted_key: str) -> str:
    """``plant.mass_kg`` -> ``mass``; ``sensors.gnss.sigma_m`` -> ``sigma``; a key named
    ``name`` is known by its section (``tracker.name`` -> ``tracker``)."""
    parts = dotted_key.split(".")
    last = parts[-1]
    if last == "name" and len(parts) > 1:
        return ""
    stem, sep, suffix = last.rpartition("_")
    if sep and stem and suffix in UNIT_SUFFIXES:
        last = stem
    return last


def _value_part(raw: str) -> str:
    safe = _safe(raw.strip())
    if safe and len(safe) <= 16 and safe == raw.strip().replace("_", "-"):
        return safe
    return hashlib.sha1(raw.encode()).hexdigest()[:6]  # a list, a mapping, a long text


def override_tag(overrides: Sequence[str] = (), tracker: str | None = None,
                 estimator: str | None = None, seed: int | None = None,
                 duration_s: float | None = None,
                 config_file: str | Sequence[str] | None = None) -> str:
    """A short, file-system-safe tag of the command-line changes to a scenario ("" for
    none), in the order: ``--config``, ``--tracker``, ``--estimator``, ``--set`` (as
    given), ``--seed``, ``--duration``."""
    parts: list[str] = []
    for name in [config_file] if isinstance(config_file, str) else (config_file or ()):
        parts.append(_safe(name.replace("\\", "/").rsplit("/", 1)[-1].rsplit(".", 1)[0]))
    if tracker and tracker.startswith("fmu:"):  # a file: its name, not its folders
        tracker = "fmu-" + tracker.replace("\\", "/").rsplit("/", 1)[-1].removesuffix(".fmu")
    parts += [_safe(name) for name in (tracker, estimator) if name]
    for text in overrides:
        key, _, value = text.partition("=")
        parts.append(_safe(_key_part(key.strip())) + _value_part(value))
    if seed is not None:
        parts.append(f"seed{seed}")
    if duration_s is not None:
        parts.append(f"{duration_s:g}s")
    tag = "-".join(p for p in parts if p)
    if len(tag) > MAX_TAG_CHARS:
        digest = hashlib.sha1(tag.encode()).hexdigest()[:6]
        tag = tag[:MAX_TAG_CHARS - 7].rstrip("-.") + "-" + digest
    return tag


def default_log_name(scenario: str, tag: str, stamp: str) -> str:
    """``<scenario>[-<tag>]-<stamp>.mcap``."""
    return "-".join(p for p in (_safe(scenario), tag, stamp) if p) + ".mcap"
