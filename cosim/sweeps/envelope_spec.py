"""An envelope spec: the mismatch parameters to search, their limits, the requirement and
the seed ensemble (``cosim envelope SPEC.yaml``; the search: :mod:`cosim.sweeps.envelope`).

Format (YAML)::

    name: mass-friction-envelope     # optional (default: the file's stem)
    scenario: lane-change            # built-in name or YAML path
    tracker: dynamic-nmpc            # optional, as in a sweep spec
    estimator: ekf                   # optional
    duration_s: 15                   # optional
    seeds: 10                        # the ensemble: a count (0..9) or a list
    set: {sensors.suite: rtk}        # optional fixed overrides
    requirement: always (abs(cte_m) <= 0.3)   # STL (cosim.simulation.requirements)
    parameters:                      # one or two: dotted path -> search limit
      plant.mass_kg: 3000            # from the scenario's value (nominal) to 3000 kg
      plant.tyre_friction: 0.3
    failure_rate: 0.1                # the boundary: where more than 10 % of seeds fail
    resolution: 0.005                # a critical value to 0.5 % of its nominal value
    max_rays: 33                     # two parameters: at most this many rays

Each parameter's nominal value is the scenario's (after ``set:``) and must be a number; a
``plant.*`` parameter's belief (``tracker.model.*``, ``tracker.latency_s``) stays at its
own value, so the search varies the mismatch, and the report names that belief. The
requirement must hold at nominal for most seeds, or there is no envelope to find.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cosim.core.exceptions import ConfigError
from cosim.core.key_aliases import canonical_key
from cosim.core.yaml_io import shown
from cosim.simulation.beliefs import counterpart
from cosim.simulation.requirements import check_formula
from cosim.sweeps.spec import SpecReader, override_text

ENVELOPE_KEYS = ("name", "description", "scenario", "tracker", "estimator", "duration_s",
                 "seeds", "set", "requirement", "parameters", "failure_rate", "resolution",
                 "max_rays", "ray_address")
"""Top-level keys an envelope spec may hold."""


@dataclass(frozen=True)
class SearchParameter:
    """One searched quantity: from its nominal value to its search limit."""

    path: str
    nominal: float
    limit: float
    belief: str | None
    """The belief key on the other side of the mismatch (None for a key in no pair)."""
    belief_value: Any

    def value(self, share: float) -> float:
        """The value ``share`` of the way from nominal to the limit (10 significant digits,
        so that a value reads back as the same override)."""
        return float(f"{self.nominal + share * (self.limit - self.nominal):.10g}")

    def share(self, value: float) -> float:
        return (value - self.nominal) / (self.limit - self.nominal)


@dataclass(frozen=True)
class EnvelopeSpec:
    """A validated envelope spec (module docstring)."""

    name: str
    description: str
    scenario: str
    tracker: str | None
    estimator: str | None
    duration_s: float | None
    seeds: tuple[int, ...]
    fixed: tuple[tuple[str, Any], ...]
    requirement: str
    parameters: tuple[SearchParameter, ...]
    failure_rate: float
    resolution: float
    max_rays: int
    ray_address: str | None
    tracker_name: str
    estimator_name: str

    def overrides(self, values: tuple[float, ...]) -> tuple[str, ...]:
        """Every ``key=value`` of the run at ``values`` (one per parameter)."""
        return (*(override_text(k, v) for k, v in self.fixed),
                *(override_text(p.path, v) for p, v in zip(self.parameters, values,
                                                           strict=True)))

    def resolution_s(self, direction: tuple[float, ...]) -> float:
        """The resolution along a ray, in its ``s``: each parameter to ``resolution`` of
        its nominal value (of its range where the nominal is 0), the finest of them."""
        steps = []
        for parameter, share in zip(self.parameters, direction, strict=True):
            if share == 0.0:
                continue
            span = abs(parameter.limit - parameter.nominal)
            scale = abs(parameter.nominal) if parameter.nominal != 0.0 else span
            steps.append(self.resolution * scale / (span * share))
        return min(steps)

    def to_dict(self) -> dict[str, Any]:
        from dataclasses import asdict

        return asdict(self)


def load_envelope_spec(path: str | Path) -> EnvelopeSpec:
    """Read and validate an envelope spec; a bad value is one line naming it."""
    from cosim.simulation.changes import flat_config
    from cosim.simulation.scenario_config import load_config

    reader = SpecReader(Path(path), "envelope spec", ENVELOPE_KEYS)
    data = reader.read()
    scenario, _ = reader.scenario(data)
    tracker = reader.optional_str(data, "tracker")
    estimator = reader.optional_str(data, "estimator")
    duration_s = reader.duration(data.get("duration_s"))
    seeds = reader.seeds(data.get("seeds"))
    fixed = tuple((canonical_key(k, reader.where) if isinstance(k, str) else k, v)
                  for k, v in reader.mapping(data, "set").items())
    requirement = data.get("requirement")
    try:
        check_formula(requirement, "requirement")
    except ConfigError as error:
        raise reader.error(str(error)) from None
    fixed = (*fixed, ("requirements", [{"formula": requirement}]))
    overrides = [override_text(k, v) for k, v in fixed]
    try:
        base = load_config(scenario, None, overrides, seeds[0], duration_s, tracker, estimator)
    except ConfigError as error:
        raise reader.error(f"config: {error}") from None
    leaves = flat_config(_plain(base))
    raw = reader.mapping(data, "parameters")
    if not 1 <= len(raw) <= 2:
        raise reader.error(f"parameters: {len(raw)} given: expected one or two dotted paths, "
                           "each with its search limit (e.g. plant.mass_kg: 3000)")
    parameters = []
    for key, limit in raw.items():
        path_key = canonical_key(str(key), reader.where)
        nominal = leaves.get(path_key)
        if path_key not in leaves:
            raise reader.error(f"parameters: {shown(key)}: unknown dotted path: expected a "
                               "config key such as plant.mass_kg")
        if not _number(nominal):
            raise reader.error(f"parameters: {path_key}: its value {shown(nominal)} is no "
                               "number: expected a numeric key")
        if not _number(limit) or float(limit) == float(nominal):
            raise reader.error(f"parameters: {path_key}: {shown(limit)}: expected a search "
                               f"limit, a number other than the nominal {nominal:g}")
        try:
            load_config(scenario, None, [*overrides, override_text(path_key, float(limit))],
                        seeds[0], duration_s, tracker, estimator)
        except ConfigError as error:
            raise reader.error(f"parameters: {path_key}: limit {limit}: {error}") from None
        belief = counterpart(path_key)
        parameters.append(SearchParameter(path_key, float(nominal), float(limit),
                                          belief, leaves.get(belief) if belief else None))
    failure_rate = data.get("failure_rate", 0.1)
    if not _number(failure_rate) or not 0.0 <= failure_rate < 1.0:
        raise reader.error(f"failure_rate: {shown(failure_rate)}: expected a share in [0, 1)")
    resolution = data.get("resolution", 0.005)
    if not _number(resolution) or not 1e-5 <= resolution <= 0.2:
        raise reader.error(f"resolution: {shown(resolution)}: expected a fraction of the "
                           "nominal value in [1e-05, 0.2] (0.005: half a per cent)")
    max_rays = data.get("max_rays", 33)
    if isinstance(max_rays, bool) or not isinstance(max_rays, int) or not 2 <= max_rays <= 65:
        raise reader.error(f"max_rays: {shown(max_rays)}: expected an integer in [2, 65]")
    return EnvelopeSpec(
        name=reader.optional_str(data, "name") or Path(path).stem,
        description=reader.description(data), scenario=scenario, tracker=tracker,
        estimator=estimator, duration_s=duration_s, seeds=seeds, fixed=fixed,
        requirement=str(requirement), parameters=tuple(parameters),
        failure_rate=float(failure_rate), resolution=float(resolution), max_rays=max_rays,
        ray_address=reader.optional_str(data, "ray_address"),
        tracker_name=base.tracker.name, estimator_name=base.estimator.name)


def _number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) \
        and math.isfinite(value)


def _plain(config: Any) -> dict[str, Any]:
    from cosim.core.config_fields import to_dict

    return to_dict(config)
