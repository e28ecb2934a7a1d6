"""The plant beside the belief: which belief key models which plant quantity, the value
``plant`` that tells the controller the truth, and a configuration's mismatch table.

cosim keeps the truth and the belief as separate data (``design.md``: "model mismatch is
the difference between the two, stated as data"). The plant (``plant.*``, ``sensors.*``)
is the real car and its real sensors; the controller's model (``tracker.model.*``, which
the filter shares), the delay it predicts over (``tracker.latency_s``) and the filter's
noise beliefs (``estimator.noise.*``) are what the software believes. Every belief has its
own key whose default is the nominal car: a plant key set alone is a mismatch, and no
belief follows the plant silently.

A user who wants the controller told writes ``plant`` as the belief's value
(``--set tracker.latency_s=plant``, ``tracker: {model: {mass_kg: plant}}``): the loader
gives it the plant's resolved value and records the request in the configuration's
``beliefs_from_plant`` (belief key -> plant key), which the log keeps and a reloaded
configuration honours.

The mismatch table (:func:`mismatch_table`) lists every pair whose plant and belief values
differ, resolved (defaults and presets included), with their ratio: what ``cosim inspect``,
a sweep's summary and the plots show.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cache
from typing import Any

from cosim.core.exceptions import ConfigError
from cosim.core.vehicle_params import PlantConfig, VehicleParams
from cosim.simulation.belief_check import SIGMA_KEYS

PLANT = "plant"
"""The belief value that asks for the plant's value (the controller is told the truth)."""

TOLD_KEY = "beliefs_from_plant"
"""The configuration's record of the beliefs told the plant's value: belief -> plant key."""


@dataclass(frozen=True)
class BeliefPair:
    """One quantity the plant has and the controller (or the filter) believes in."""

    quantity: str
    """The quantity's name with its unit (``mass_kg``, ``actuator_delay_s``)."""
    plant_key: str
    belief_key: str


@cache
def belief_pairs() -> tuple[BeliefPair, ...]:
    """Every (plant key, belief key) pair: each car parameter the plant and the
    controller's model share (``plant.X`` and ``tracker.model.X``), the actuator delay
    (``plant.actuator_delay_s`` and ``tracker.latency_s``), and each fused sensor's noise
    (``sensors.*`` and ``estimator.noise.*``)."""
    plant_fields = [f.name for f in dataclasses.fields(PlantConfig)]
    belief_fields = {f.name for f in dataclasses.fields(VehicleParams)}
    pairs = [BeliefPair(name, f"plant.{name}", f"tracker.model.{name}")
             for name in plant_fields if name in belief_fields]
    pairs.append(BeliefPair("actuator_delay_s", "plant.actuator_delay_s", "tracker.latency_s"))
    for keys in SIGMA_KEYS.values():
        for truth, belief in keys:
            pairs.append(BeliefPair(belief.rsplit(".", 1)[1], truth, belief))
    return tuple(pairs)


def counterpart(key: str) -> str | None:
    """The other side of ``key``'s plant/belief pair (None for a key in no pair)."""
    for pair in belief_pairs():
        if key == pair.plant_key:
            return pair.belief_key
        if key == pair.belief_key:
            return pair.plant_key
    return None


def _get(data: Any, dotted: str) -> Any:
    node = data
    for part in dotted.split("."):
        if not isinstance(node, Mapping) or part not in node:
            return None
        node = node[part]
    return node


def _pop(data: dict[str, Any], dotted: str) -> None:
    *parents, leaf = dotted.split(".")
    node: Any = data
    for part in parents:
        node = node.get(part) if isinstance(node, dict) else None
    if isinstance(node, dict):
        node.pop(leaf, None)


def take_plant_requests(data: dict[str, Any]) -> dict[str, str]:
    """Take every belief set to ``plant`` out of ``data`` (raw configuration dictionaries,
    changed in place) and return them as belief key -> plant key; a recorded
    ``beliefs_from_plant`` (a logged or shown configuration) asks for the same.

    ``plant`` on a key that is no belief, or a record naming one, is refused in one line."""
    requests: dict[str, str] = {}
    recorded = data.pop(TOLD_KEY, None)
    if recorded is not None and not isinstance(recorded, Mapping):
        raise ConfigError(f"{TOLD_KEY} = {recorded!r}: expected a mapping of belief keys "
                          "to plant keys (or write the belief as `plant`)")
    for key in recorded or {}:
        if counterpart(str(key)) is None or not str(key).startswith(("tracker.", "estimator.")):
            raise ConfigError(f"{TOLD_KEY}: {key!r} is no belief key: expected one of "
                              f"{', '.join(p.belief_key for p in belief_pairs()[:3])} ...")
        requests[str(key)] = counterpart(str(key))  # type: ignore[assignment]
    for pair in belief_pairs():
        if _get(data, pair.belief_key) == PLANT:
            requests[pair.belief_key] = pair.plant_key
    for key in requests:
        _pop(data, key)
    for pair in belief_pairs():
        if _get(data, pair.plant_key) == PLANT:
            raise ConfigError(f"{pair.plant_key} = 'plant': the plant is the truth; `plant` "
                              f"is a belief's value (expected e.g. {pair.belief_key}=plant)")
    return requests


def _replace_dotted(config: Any, dotted: str, value: Any) -> Any:
    head, _, rest = dotted.partition(".")
    if not rest:
        return dataclasses.replace(config, **{head: value})
    return dataclasses.replace(
        config, **{head: _replace_dotted(getattr(config, head), rest, value)})


def tell(config: Any, requests: Mapping[str, str]) -> Any:
    """``config`` (a :class:`~cosim.simulation.scenario_config.ScenarioConfig`) with each
    requested belief given its plant key's resolved value, and the requests recorded."""
    for belief_key, plant_key in requests.items():
        config = _replace_dotted(config, belief_key, _value_of(config, plant_key))
    return dataclasses.replace(config, **{TOLD_KEY: dict(requests)})


def _value_of(config: Any, dotted: str) -> Any:
    node = config
    for part in dotted.split("."):
        node = getattr(node, part)
    return node


@dataclass(frozen=True)
class MismatchRow:
    """One quantity whose plant value and belief differ."""

    quantity: str
    plant_key: str
    belief_key: str
    plant: Any
    belief: Any
    ratio: float | None
    """plant / belief, how many times the belief the truth is (None unless both are
    numbers and the belief is not zero)."""

    def as_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    def text(self) -> str:
        """``mass_kg: plant 2000, belief 1575 (plant/belief 1.27)``."""
        ratio = f" (plant/belief {self.ratio:.3g})" if self.ratio is not None else ""
        return f"{self.quantity}: plant {_shown(self.plant)}, belief {_shown(self.belief)}{ratio}"


def _shown(value: Any) -> str:
    return f"{value:g}" if isinstance(value, float) else str(value)


def _number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def mismatch_table(config: Mapping[str, Any]) -> list[MismatchRow]:
    """Every pair of :func:`belief_pairs` whose values differ in ``config`` (a resolved
    configuration as nested dictionaries, as a log holds it), in the pairs' order. A pair
    one side of which the configuration lacks (a log of an older cosim) is left out; so are
    the noise beliefs of a disabled sensor."""
    rows = []
    for pair in belief_pairs():
        plant, belief = _get(config, pair.plant_key), _get(config, pair.belief_key)
        if plant is None or belief is None:
            continue
        if pair.plant_key.startswith("sensors.") and \
                _get(config, pair.plant_key.rsplit(".", 1)[0] + ".enabled") is False:
            continue
        same = (math.isclose(float(plant), float(belief), rel_tol=1e-12, abs_tol=0.0)
                if _number(plant) and _number(belief) else plant == belief)
        if same:
            continue
        ratio = (float(plant) / float(belief) if _number(plant) and _number(belief)
                 and float(belief) != 0.0 else None)
        rows.append(MismatchRow(pair.quantity, pair.plant_key, pair.belief_key, plant,
                                belief, ratio))
    return rows


def told(config: Mapping[str, Any]) -> dict[str, str]:
    """The beliefs ``config`` (as nested dictionaries) was told from the plant."""
    recorded = config.get(TOLD_KEY)
    return dict(recorded) if isinstance(recorded, Mapping) else {}


def mismatch_line(config: Mapping[str, Any]) -> str:
    """The mismatch table in one line for a person: ``mismatch (plant vs belief): mass_kg:
    plant 2000, belief 1575 (plant/belief 1.27)``, and which beliefs were told the plant's value."""
    rows = mismatch_table(config)
    text = ("mismatch (plant vs belief): " + "; ".join(r.text() for r in rows) if rows
            else "mismatch: none (every belief is the plant's value)")
    requests = told(config)
    if requests:
        text += "; told the plant's value: " + ", ".join(requests)
    return text


def mismatch_short(config: Mapping[str, Any]) -> str:
    """The mismatch table for a figure's title: ``plant vs belief: mass_kg 2000 vs 1575``
    (``""`` when every belief is the plant's value)."""
    rows = mismatch_table(config)
    if not rows:
        return ""
    return "plant vs belief: " + ", ".join(
        f"{r.quantity} {_shown(r.plant)} vs {_shown(r.belief)}" for r in rows)
