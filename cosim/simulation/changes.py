"""What a run changed from its scenario, as ``key=value`` lines a person reads.

A run's configuration is a built-in scenario plus changes: ``--set`` overrides, a
``--config`` file, ``--tracker``, or a whole scenario file that started as a copy of a
built-in one. Plot titles, ``cosim inspect`` and log names show these changes, so two runs
of one scenario never look alike when they are not (``plant.mass_kg=2000`` on the heavy
run's figures, and ``mass2000`` in its file name).

The base a configuration is compared with is the built-in scenario of its name, or, for a
scenario file whose name is not a built-in's, the built-in whose own YAML it agrees with
most (key by key); the comparison is between resolved configurations (every default
filled in), so a change is listed whether it was written as a ``--set``, in a file, or by
choosing a component. The seed, the name and the description are not changes (the seed is
shown beside them). Keys that follow another change are left out: the steering bound and the
steering-rate weight that follow the tracker (``tracker.max_steer_rad``,
``tracker.weights.steer_rate``: each tracker's default) and the sensor
figures and filter beliefs a ``sensors.suite`` preset brings. A belief told the plant's
value (:mod:`cosim.simulation.beliefs`) shows as that request, ``tracker.latency_s=plant``,
not as the number it took: two runs that differ in what the controller was told never look
alike.
"""

from __future__ import annotations

import importlib.resources
import warnings
from collections.abc import Mapping, Sequence
from typing import Any

from cosim.core.config_fields import to_dict
from cosim.core.exceptions import CosimError
from cosim.core.yaml_io import loads as yaml_loads
from cosim.simulation.beliefs import PLANT, TOLD_KEY, counterpart, told
from cosim.simulation.scenario_config import ConfigMergeNote, builtin_scenarios, load_config
from tracker.config import own_defaults

NOT_CHANGES = ("name", "description", "seed")
"""Keys that tell runs apart without being changes to the scenario."""


def flat_config(config: Any, prefix: str = "") -> dict[str, Any]:
    """A nested configuration as ``dotted.key -> value`` (lists as ``key[i]``)."""
    if isinstance(config, Mapping):
        flat: dict[str, Any] = {}
        for key, value in config.items():
            flat.update(flat_config(value, f"{prefix}.{key}" if prefix else str(key)))
        return flat
    if isinstance(config, list):
        flat = {}
        for i, value in enumerate(config):
            flat.update(flat_config(value, f"{prefix}[{i}]"))
        return flat or {prefix: "[]"}
    return {prefix: config}


def config_differences(configs: Sequence[Mapping[str, Any]]) -> list[str]:
    """The dotted keys whose values differ between configurations, in the order of the
    first one (a key only some of them have counts as different); ``description`` is left
    out. Between configurations of different trackers, a key whose default follows the
    tracker (:func:`tracker.config.own_defaults`) differs where one of them leaves its own
    tracker's default, whether or not the numbers are equal."""
    flats = [flat_config(config) for config in configs]
    keys = list(dict.fromkeys(key for flat in flats for key in flat))
    missing = object()
    trackers_differ = len({repr(flat.get("tracker.name")) for flat in flats}) > 1
    own = _own_defaults_left(flats) if trackers_differ else {}
    return [key for key in keys
            if key != "description"
            and (own[key] if key in own
                 else len({repr(flat.get(key, missing)) for flat in flats}) > 1)]


def shown_difference(key: str, flat: Mapping[str, Any]) -> str:
    """``key=value`` of one differing key in a flat configuration; a belief told the
    plant's value (``beliefs_from_plant.<belief>``) shows as ``<belief>=plant``, or the
    belief's own value in a configuration that did not ask."""
    if key.startswith(f"{TOLD_KEY}."):
        belief = key.removeprefix(f"{TOLD_KEY}.")
        value = shown_value(flat.get(belief))
        return f"{belief}={PLANT} ({value})" if key in flat else f"{belief}={value}"
    return f"{key}={shown_value(flat.get(key))}"


def mismatch_first(keys: Sequence[str]) -> list[str]:
    """``keys`` with the two sides of a model mismatch first (plant and belief keys of
    :func:`cosim.simulation.beliefs.belief_pairs`, and told beliefs), each group in its
    order: what decides a mismatch study is named before anything else. A belief whose
    request to be told differs too is named once, by the request."""
    def is_pair(key: str) -> bool:
        return key.startswith(f"{TOLD_KEY}.") or counterpart(key) is not None

    # A told belief's request shows its value too (shown_difference): named once.
    keys = [k for k in keys if f"{TOLD_KEY}.{k}" not in keys]
    return [k for k in keys if is_pair(k)] + [k for k in keys if not is_pair(k)]


def _own_defaults_left(flats: Sequence[Mapping[str, Any]]) -> dict[str, bool]:
    """For each key whose default follows the tracker (:func:`tracker.config.own_defaults`),
    whether some flat configuration holds another value than its own tracker's default."""
    defaults = [{f"tracker.{key}": value for key, value in
                 own_defaults(str(flat.get("tracker.name"))).items()} for flat in flats]
    return {key: any(flat.get(key) != own[key] for flat, own in zip(flats, defaults, strict=True))
            for key in defaults[0]}


def shown_value(value: Any) -> str:
    """A configuration value as a change shows it (``2000``, ``0.1``, ``gnss``)."""
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, bool):
        return "true" if value else "false"
    return "n/a" if value is None else str(value)


def _builtin_yaml(name: str) -> dict[str, Any]:
    resource = importlib.resources.files("cosim.scenarios") / f"{name}.yaml"
    return yaml_loads(resource.read_text()) or {}


def base_scenario(config: Mapping[str, Any]) -> str | None:
    """The built-in scenario a configuration (as logged: nested dictionaries) started from:
    the one of its name, else the one whose YAML it agrees with most; None when there are
    no built-in scenarios to compare with."""
    builtins = list(builtin_scenarios())
    name = str(config.get("name", ""))
    if name in builtins:
        return name
    flat = flat_config(config)

    def disagreements(builtin: str) -> tuple[int, int]:
        own = flat_config(_builtin_yaml(builtin))
        own = {k: v for k, v in own.items() if k.split(".")[0] not in NOT_CHANGES}
        return (sum(repr(flat.get(k)) != repr(v) for k, v in own.items()), -len(own))

    return min(builtins, key=disagreements) if builtins else None


def config_changes(config: Mapping[str, Any]) -> list[str]:
    """``key=value`` for each change of ``config`` (a resolved configuration as nested
    dictionaries, e.g. the one a log holds) from its :func:`base_scenario`."""
    base_name = base_scenario(config)
    if base_name is None:
        return []
    try:
        base = to_dict(load_config(base_name))
        flat = flat_config(config)
        presets = []
        changes = []
        for key in ("car", "sensors.suite"):  # what a preset brings is not a change
            value = flat.get(key)
            if value is not None and value != flat_config(base).get(key):
                presets.append(f"{key}={value}")
        if presets:
            base = to_dict(load_config(base_name, overrides=presets))
            changes += presets
    except CosimError:  # a log from another version whose keys this one lacks
        return []
    requests = told(config)
    for key in config_differences([base, config]):
        if key.split(".")[0].split("[")[0] in NOT_CHANGES:
            continue
        if key.startswith(f"{TOLD_KEY}."):  # a told belief: the request, not its number
            belief = key.removeprefix(f"{TOLD_KEY}.")
            if belief in requests:
                changes.append(f"{belief}={PLANT}")
            continue
        if key in requests:
            continue
        if key == "initial.speed_mps" and flat.get("initial.speed_from_profile"):
            continue  # the profile's speed, resolved by the run: not a change
        if key in flat:  # a key the log lacks is one its cosim did not have yet
            changes.append(f"{key}={shown_value(flat.get(key))}")
    return changes


def changes_text(changes: Sequence[str], at_most: int = 4) -> str:
    """A list of changes in a few words: the first ``at_most``, then ``+n more``."""
    if not changes:
        return "as the scenario"
    shown = ", ".join(changes[:at_most])
    more = len(changes) - at_most
    return shown + (f", +{more} more" if more > 0 else "")


def file_changes(scenario: str, config_file: str | Sequence[str] | None = None) -> list[str]:
    """What files change (for a log's name): a scenario file's changes from its base
    scenario, and what the ``--config`` files change in the scenario; ``[]`` for a built-in
    scenario without a ``--config``."""
    changes: list[str] = []
    if scenario not in builtin_scenarios():
        changes += config_changes(to_dict(load_config(scenario)))
    if config_file:
        with warnings.catch_warnings():  # the run's own load says it, once
            warnings.simplefilter("ignore", ConfigMergeNote)
            alone = to_dict(load_config(scenario))
            merged = to_dict(load_config(scenario, config_file))
        flat = flat_config(merged)
        changes += [f"{key}={shown_value(flat.get(key))}"
                    for key in config_differences([alone, merged])
                    if key.split(".")[0] not in NOT_CHANGES]
    return list(dict.fromkeys(changes))
