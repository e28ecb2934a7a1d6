"""A sweep spec: what is varied, over which values and seeds, and what counts as a pass.

A spec is a YAML mapping::

    name: mass-friction              # optional; default: the file's stem
    scenario: lane-change            # built-in name or a YAML path (relative to the spec)
    tracker: dynamic-nmpc            # optional; default: the scenario's
    estimator: ekf                   # optional; default: the scenario's
    duration_s: 15                   # optional; default: the scenario's
    seeds: 2                         # a count (seeds 0, 1) or a list ([0, 7])
    set:                             # optional fixed overrides, dotted path -> value
      sensors.suite: rtk
    grid:                            # full factorial, dotted path -> list of values
      plant.mass_kg: [1100, 1575, 2050]
      plant.tyre_friction: [0.6, 0.8, 1.0]
    # or, instead of grid:
    # random: {n: 20, seed: 7, plant.mass_kg: [1100, 2050]}   # uniform in [low, high]
    pass:                            # optional; upper bounds, or true/false for booleans
      cte_max_m: 0.3
      completed: true
      gap_min_m: {min: 5}            # a lower bound (a *_min metric must say which)
      stl: always (abs(cte_m) <= 0.3)  # STL requirements (or a list): each run must
                                     # satisfy them (robustness >= 0, a metric of its own;
                                     # cosim.simulation.requirements)
    metric: cte_max_m                # optional headline metric of the summary and plots
                                     # (a list plots each: [gap_min_m, ttc_min_s]);
                                     # default: the first numeric pass criterion
    ray_address: ray://head:10001    # optional, --backend ray only

Every varied quantity is a :class:`Parameter`: its dotted path, its nominal value (the
scenario's, after ``set:``) and its values or range. ``plant.*`` is the simulated car (the
truth) and ``tracker.model.*`` the controller's belief, so varying one and not the other is
a model mismatch; the summary shows both sides.

Validation happens here, before any run: every dotted path must be a key of the scenario's
configuration, every grid value and both ends of every random range must pass the
configuration's own checks (``ConfigError`` names the key and the accepted range), and
every pass criterion must name a metric a run produces
(:func:`cosim.simulation.fail_if.metric_kind`: the traffic, course and manoeuvre metrics too).

The list of runs (:meth:`SweepSpec.tasks`) depends on the spec only: per-run seeds are the
spec's seeds, random values come from a generator seeded by ``random.seed``, and run ids
number the runs point-major, seed-minor. Whatever executes them, the same spec gives the
same runs.
"""

from __future__ import annotations

import dataclasses
import difflib
import hashlib
import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from cosim.core.exceptions import ConfigError
from cosim.core.key_aliases import canonical_key
from cosim.core.yaml_io import read_yaml_file, shown
from cosim.simulation.beliefs import counterpart, mismatch_table
from cosim.simulation.fail_if import FLAG, NUMBER, WORD, known_metrics, metric_kind
from cosim.simulation.metric_keys import METRIC_KEYS, metric_key
from cosim.simulation.requirements import check_formula
from tracker.config import is_plugin_name
from tracker.plugins.loading import resolved_params

Scalar = float | int | bool | str
"""A value a varied parameter can take."""

MAX_SEEDS = 1_000_000
"""A seed count above this is refused outright (the list alone would fill memory)."""

BOOLEAN_METRICS = tuple(key for key in METRIC_KEYS if metric_key(key).unit == "bool")
"""Metrics that are true or false; every other metric of METRIC_KEYS is a number."""

DEFAULT_METRIC = "cte_max_m"
"""Headline metric when the spec names none and has no numeric pass criterion."""

RANDOM_DIGITS = 6
"""Random values are rounded to this many significant digits, so tables stay readable."""

SPEC_KEYS = ("name", "description", "scenario", "tracker", "estimator", "duration_s", "seeds",
             "set", "grid", "random", "pass", "metric", "ray_address")
"""Top-level keys a spec may hold."""

MAX_DESCRIPTION_CHARS = 10_000
"""The longest ``description:`` a spec may have (it is copied into every summary)."""

_UNITS = (
    ("_kgm2", "kg m²"), ("_mps2", "m/s²"), ("_radps", "rad/s"), ("_nspm", "N s/m"),
    ("_npm", "N/m"), ("_npr", "N/rad"), ("_prad", "1/rad"), ("_mps", "m/s"), ("_rad", "rad"),
    ("_kg", "kg"), ("_m2", "m²"), ("_nm", "N m"), ("_hz", "Hz"), ("_m", "m"), ("_s", "s"),
    ("_w", "W"), ("_n", "N"),
)
"""Unit of a key from its name's suffix (the project's convention: units in names)."""


def unit_of(key: str) -> str:
    """The unit a dotted key's name carries (``plant.mass_kg`` -> ``kg``); ``-`` if none."""
    leaf = key.rsplit(".", 1)[-1]
    for suffix, unit in _UNITS:
        if leaf.endswith(suffix):
            return unit
    return "-"


def axis_label(key: str) -> str:
    """``plant.mass_kg [kg]``: a dotted key with its unit, for tables and plot axes."""
    return f"{key} [{unit_of(key)}]"


STL_KEY = "stl"
"""The ``pass:`` key of STL requirements (:meth:`SpecReader.formulas`)."""


def override_text(key: str, value: Any) -> str:
    """``key=value`` as :func:`~cosim.simulation.scenario_config.parse_override` reads it back.

    The value is written as YAML (PyYAML reads ``1e-05`` as a string, ``1.0e-05`` as a
    float, so plain ``str(value)`` would not do).
    """
    text = yaml.safe_dump(value, default_flow_style=True, width=10**6)
    return f"{key}={text.removesuffix(chr(10)).removesuffix('...').strip()}"


@dataclass(frozen=True)
class Parameter:
    """One varied quantity: a dotted config path, its nominal value and its values or range.

    ``counterpart`` is the other side of a mismatch: for ``plant.X`` the tracker's belief
    ``tracker.model.X``, for ``tracker.model.X`` the plant's ``plant.X``, for
    ``plant.actuator_delay_s`` ``tracker.latency_s`` (``None`` when the key has no
    counterpart); ``counterpart_value`` is its value in the sweep's base config.
    """

    path: str
    nominal: Any
    values: tuple[Scalar, ...] = ()
    """The grid values (grid sweeps)."""
    low: float | None = None
    """Lower end of the uniform range (random sweeps)."""
    high: float | None = None
    """Upper end of the uniform range (random sweeps)."""
    counterpart: str | None = None
    counterpart_value: Any = None

    @property
    def unit(self) -> str:
        return unit_of(self.path)

    @property
    def label(self) -> str:
        return axis_label(self.path)

    def describe_values(self) -> str:
        if self.values:
            return ", ".join(_format(v) for v in self.values)
        return f"uniform in [{_format(self.low)}, {_format(self.high)}]"


@dataclass(frozen=True)
class PassCriterion:
    """``lower <= metric <= bound`` for a number (``bound`` infinite: no upper bound),
    ``metric == bound`` for a boolean metric."""

    metric: str
    bound: float | bool
    lower: float = -math.inf
    label: str = ""
    """How the criterion reads when its metric does not say it (an STL requirement's
    formula, for its ``stl_robustness_<i> >= 0``)."""

    def describe(self) -> str:
        if self.label:
            return self.label
        if isinstance(self.bound, bool):
            return f"{self.metric} is {str(self.bound).lower()}"
        unit = unit_of(self.metric)
        if math.isinf(self.lower):
            text = f"{self.metric} <= {_format(self.bound)} {unit}"
        elif math.isinf(self.bound):
            text = f"{self.metric} >= {_format(self.lower)} {unit}"
        else:
            text = f"{_format(self.lower)} <= {self.metric} <= {_format(self.bound)} {unit}"
        return text.rstrip(" -")

    def failure(self, metrics: dict[str, Any]) -> str | None:
        """Why ``metrics`` fail this criterion (``None`` when they pass)."""
        value = metrics.get(self.metric)
        if isinstance(self.bound, bool):
            return None if value is self.bound else f"{self.metric}={_format(value)}"
        if not isinstance(value, (int, float)) or isinstance(value, bool) \
                or not math.isfinite(value):
            return f"{self.metric}=n/a"
        if value > self.bound:
            return f"{self.metric}={value:.4g}>{self.bound:g}"
        if value < self.lower:
            return f"{self.metric}={value:.4g}<{self.lower:g}"
        return None


@dataclass(frozen=True)
class RunTask:
    """One run of a sweep, in plain values (it crosses process and machine boundaries)."""

    run_id: int
    point: int
    """Index of the parameter point (runs of one point differ only by seed)."""
    seed: int
    params: tuple[tuple[str, Scalar], ...]
    """The varied values of this run, (dotted path, value), in the spec's order."""
    scenario: str
    overrides: tuple[str, ...]
    """Every ``key=value`` override of the run: the spec's ``set:``, then ``params``."""
    tracker: str | None
    estimator: str | None
    duration_s: float | None
    log_path: str | None
    """Where the run's MCAP log goes; ``None``: no log at all
    (:func:`cosim.simulation.runner.run_unlogged`, the same metrics bit for bit)."""


@dataclass(frozen=True)
class SweepSpec:
    """A validated sweep spec (see the module docstring for the YAML)."""

    name: str
    description: str
    scenario: str
    tracker: str | None
    estimator: str | None
    duration_s: float | None
    seeds: tuple[int, ...]
    fixed: tuple[tuple[str, Any], ...]
    """The ``set:`` overrides, (dotted path, value)."""
    mode: str
    """``grid``, ``random``, or ``seeds`` (nothing varied but the seed)."""
    parameters: tuple[Parameter, ...]
    random_n: int
    random_seed: int
    criteria: tuple[PassCriterion, ...]
    metric: str
    """The headline metric of the summary and the plots."""
    ray_address: str | None
    scenario_text: str = ""
    """The scenario file's text when the scenario is a file (part of the spec's hash)."""
    tracker_name: str = ""
    """The tracker the runs use (``tracker``, else the scenario's), for titles."""
    estimator_name: str = ""
    """The estimator the runs use (``estimator``, else the scenario's), for titles."""
    also_plotted: tuple[str, ...] = ()
    """Further metrics plotted against each parameter (``metric:`` given as a list)."""
    base_mismatch: tuple[str, ...] = ()
    """The base configuration's mismatch table, a line a row
    (:func:`cosim.simulation.beliefs.mismatch_table`): plant against belief before any
    varied value (derived from the rest: not part of the hash)."""

    @property
    def metrics(self) -> tuple[str, ...]:
        """Every metric the plots show: the headline first."""
        return (self.metric, *self.also_plotted)

    @property
    def n_runs(self) -> int:
        """How many runs the spec asks for (computed without listing them)."""
        points = {"grid": math.prod(len(p.values) for p in self.parameters),
                  "random": self.random_n, "seeds": 1}[self.mode]
        return points * len(self.seeds)

    def points(self) -> list[tuple[Scalar, ...]]:
        """The parameter points, one value per parameter, in run-id order."""
        if self.mode == "grid":
            points: list[tuple[Scalar, ...]] = [()]
            for parameter in self.parameters:  # the last parameter varies fastest
                points = [(*p, v) for p in points for v in parameter.values]
            return points
        if self.mode == "random":
            import numpy as np

            rng = np.random.default_rng(self.random_seed)
            lows = [p.low for p in self.parameters]
            highs = [p.high for p in self.parameters]
            samples = rng.uniform(lows, highs, size=(self.random_n, len(self.parameters)))
            return [tuple(float(f"{v:.{RANDOM_DIGITS}g}") for v in row) for row in samples]
        return [()]

    def tasks(self, log_dir: Path | None = None) -> list[RunTask]:
        """Every run of the sweep, by run id; logs go to ``log_dir`` when it is given."""
        fixed = tuple(override_text(k, v) for k, v in self.fixed)
        tasks = []
        for point_index, point in enumerate(self.points()):
            params = tuple((p.path, v) for p, v in zip(self.parameters, point, strict=True))
            overrides = fixed + tuple(override_text(k, v) for k, v in params)
            for seed in self.seeds:
                run_id = len(tasks)
                log = None if log_dir is None else str(log_dir / f"run-{run_id:04d}.mcap")
                tasks.append(RunTask(run_id, point_index, seed, params, self.scenario,
                                     overrides, self.tracker, self.estimator, self.duration_s,
                                     log))
        return tasks

    def to_dict(self) -> dict[str, Any]:
        """The spec as plain data (what ``sweep.json`` stores and the hash covers)."""
        data = dataclasses.asdict(self)
        data.pop("scenario_text")
        data.pop("base_mismatch")
        for criterion in data["criteria"]:  # plain JSON, and the hash of specs before it
            for key in ("bound", "lower"):
                if isinstance(criterion[key], float) and math.isinf(criterion[key]):
                    criterion.pop(key)
            if not criterion["label"]:
                criterion.pop("label")
        return json.loads(json.dumps(data, default=str))

    def digest(self) -> str:
        """SHA-256 of the spec's content (and the scenario file's): resume refuses another."""
        canonical = json.dumps(self.to_dict(), sort_keys=True) + "\n" + self.scenario_text
        return hashlib.sha256(canonical.encode()).hexdigest()


def _format(value: Any) -> str:
    if isinstance(value, bool) or value is None:
        return {True: "true", False: "false", None: "n/a"}[value]
    if isinstance(value, float):
        return f"{value:g}" if math.isfinite(value) else "n/a"
    return str(value)


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) \
        and math.isfinite(value)


def _leaves(data: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """Every leaf of a nested mapping by dotted path (lists are leaves)."""
    leaves: dict[str, Any] = {}
    for key, value in data.items():
        path = f"{prefix}{key}"
        if isinstance(value, dict):
            leaves.update(_leaves(value, path + "."))
        else:
            leaves[path] = value
    return leaves


class SpecReader:
    """Reads and validates one spec file; every error names the file and the bad value."""

    def __init__(self, path: Path, what: str = "sweep spec",
                 keys: tuple[str, ...] | None = None) -> None:
        self.path = path
        self.what = what
        self.keys = keys if keys is not None else SPEC_KEYS
        self.where = f"{what} {str(path)!r}"

    def error(self, message: str) -> ConfigError:
        return ConfigError(f"{self.where}: {message}")

    def read(self) -> dict[str, Any]:
        data = read_yaml_file(self.path, self.what)
        if not isinstance(data, dict):
            raise self.error(f"expected a mapping with {', '.join(self.keys[:4])} ...")
        unknown = sorted(set(data) - set(self.keys), key=str)
        if unknown:
            other = {"sweep spec": ("envelope", ("requirement", "parameters", "failure_rate",
                                                 "resolution", "max_rays")),
                     "envelope spec": ("sweep", ("grid", "random", "pass", "metric"))}
            command, keys = other.get(self.what, ("", ()))
            hint = (f" (an {command} spec? run `cosim {command}` on it)"
                    if command == "envelope" and unknown[0] in keys else
                    f" (a {command} spec? run `cosim {command}` on it)"
                    if command and unknown[0] in keys else "")
            raise self.error(f"unknown key {shown(unknown[0])}{hint}: expected one of "
                             f"{', '.join(self.keys)}")
        return data

    def description(self, data: dict[str, Any]) -> str:
        """``description:``, text of at most :data:`MAX_DESCRIPTION_CHARS` (a list of YAML
        aliases would expand into gigabytes of summary)."""
        value = data.get("description")
        if value is None:
            return ""
        if not isinstance(value, str):
            raise self.error(f"description: a {type(value).__name__}: expected text")
        if len(value) > MAX_DESCRIPTION_CHARS:
            raise self.error(f"description: {len(value):,} characters: expected at most "
                             f"{MAX_DESCRIPTION_CHARS:,}")
        return value

    def optional_str(self, data: dict[str, Any], key: str) -> str | None:
        value = data.get(key)
        if value is not None and not isinstance(value, str):
            raise self.error(f"{key}: {shown(value)}: expected a name")
        return value

    def scenario(self, data: dict[str, Any]) -> tuple[str, str]:
        """The scenario as load_config takes it, and the file's text when it is a file."""
        scenario = data.get("scenario")
        if not isinstance(scenario, str) or not scenario:
            raise self.error(f"scenario: {shown(scenario)}: expected a built-in name or a "
                             "YAML path")
        if scenario.endswith((".yaml", ".yml")):
            candidate = self.path.parent / scenario
            path = candidate if candidate.is_file() else Path(scenario)
            if not path.is_file():
                raise self.error(f"scenario: {shown(scenario)}: no such file")
            read_yaml_file(path, "scenario")  # refuses a file that is not UTF-8 YAML
            return str(path.resolve()), path.read_text(encoding="utf-8-sig")
        return scenario, ""

    def seeds(self, value: Any) -> tuple[int, ...]:
        if value is None:
            return (0,)
        if isinstance(value, int) and not isinstance(value, bool):
            if not 1 <= value <= MAX_SEEDS:
                raise self.error(f"seeds: {value}: expected a count in [1, {MAX_SEEDS}] or a "
                                 "list of seeds")
            return tuple(range(value))
        if not isinstance(value, list) or not value:
            raise self.error(f"seeds: {shown(value)}: expected a count >= 1 or a list of seeds")
        for seed in value:
            if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
                raise self.error(f"seeds: {shown(seed)}: expected an integer >= 0")
        if len(set(value)) != len(value):
            raise self.error(f"seeds: {value}: expected each seed once")
        return tuple(value)

    def mapping(self, data: dict[str, Any], key: str) -> dict[str, Any]:
        value = data.get(key)
        if value is None:
            return {}
        if not isinstance(value, dict):
            raise self.error(f"{key}: {shown(value)}: expected a mapping of dotted paths to values")
        return value

    def duration(self, value: Any) -> float | None:
        if value is None:
            return None
        if not _is_number(value) or value <= 0:
            raise self.error(f"duration_s: {shown(value)}: expected a number of seconds > 0")
        return float(value)

    def criteria(self, data: dict[str, Any]) -> tuple[PassCriterion, ...]:
        criteria = []
        for metric, bound in self.mapping(data, "pass").items():
            if metric == STL_KEY:  # requirements: :meth:`formulas`
                continue
            kind = metric_kind(str(metric))
            if kind is None:
                close = difflib.get_close_matches(str(metric), known_metrics(), n=1)
                hint = f" (did you mean {close[0]}?)" if close else ""
                raise self.error(f"pass: unknown metric {shown(metric)}{hint}: expected a "
                                 "metric of `cosim inspect --json` (e.g. cte_max_m)")
            if kind == WORD:
                raise self.error(f"pass: {metric}: a word, not a number: expected a numeric "
                                 "or true/false metric (e.g. completed: true)")
            if kind == FLAG:
                if not isinstance(bound, bool):
                    raise self.error(f"pass: {metric}: {shown(bound)}: expected true or false")
                criteria.append(PassCriterion(str(metric), bound))
                continue
            criteria.append(self.range_criterion(str(metric), bound))
        return tuple(criteria)

    def formulas(self, data: dict[str, Any]) -> tuple[str, ...]:
        """``pass: {stl: FORMULA}`` (or a list of them): STL requirements every run must
        satisfy, each checked here (:mod:`cosim.simulation.requirements`)."""
        value = self.mapping(data, "pass").get(STL_KEY)
        if value is None:
            return ()
        formulas = [value] if isinstance(value, str) else value
        if not isinstance(formulas, list) or not formulas:
            raise self.error(f"pass: {STL_KEY}: {shown(value)}: expected an STL formula or a "
                             "list of them (e.g. always (abs(cte_m) <= 0.3))")
        for index, formula in enumerate(formulas):
            try:
                check_formula(formula, f"pass: {STL_KEY}[{index}]")
            except ConfigError as error:
                raise self.error(str(error)) from None
        return tuple(formulas)

    def sampling(self, data: dict[str, Any]) -> tuple[str, dict[Any, Any], int, int]:
        """``(mode, ranges, random_n, random_seed)``: ``grid`` with its lists, ``random``
        with its ranges, sample count and seed, or ``seeds`` alone."""
        grid, random = data.get("grid"), data.get("random")
        if grid is not None and random is not None:
            raise self.error("expected either grid: or random:, not both")
        if grid is not None:
            ranges = self.mapping(data, "grid")
            if not ranges:
                raise self.error("grid: empty: expected at least one dotted path with a list "
                                 "of values")
            return "grid", ranges, 0, 0
        if random is None:
            return "seeds", {}, 0, 0
        ranges = dict(self.mapping(data, "random"))
        random_n, random_seed = ranges.pop("n", None), ranges.pop("seed", 0)
        if isinstance(random_n, bool) or not isinstance(random_n, int) or random_n < 1:
            raise self.error(f"random: n: {shown(random_n)}: expected a number of samples >= 1")
        if isinstance(random_seed, bool) or not isinstance(random_seed, int) or random_seed < 0:
            raise self.error(f"random: seed: {shown(random_seed)}: expected an integer >= 0")
        if not ranges:
            raise self.error("random: expected at least one dotted path -> [low, high] "
                             "besides n and seed")
        return "random", ranges, random_n, random_seed
    def range_criterion(self, metric: str, bound: Any) -> PassCriterion:
        """A bare number is an upper bound; ``{min: X}``, ``{max: Y}`` or both say which."""
        unit = unit_of(metric)
        if isinstance(bound, dict):
            extra = sorted(set(bound) - {"min", "max"}, key=str)
            values = list(bound.values())
            if extra or not bound or not all(_is_number(v) for v in values):
                raise self.error(f"pass: {metric}: {shown(bound)}: expected {{min: X}}, "
                                 f"{{max: Y}} or both, numbers in {unit}")
            low, high = float(bound.get("min", -math.inf)), float(bound.get("max", math.inf))
            if low > high:
                raise self.error(f"pass: {metric}: {shown(bound)}: expected min <= max")
            return PassCriterion(metric, high, low)
        if not _is_number(bound):
            raise self.error(f"pass: {metric}: {shown(bound)}: expected a number "
                             f"(an upper bound in {unit}) or {{min: X}}")
        if "_min" in metric:  # "gap_min_m: 5" reads as "at least 5": say which is meant
            raise self.error(f"pass: {metric}: {shown(bound)}: {metric} is a minimum: "
                             f"expected {{min: {bound}}} (at least) or {{max: {bound}}} "
                             "(at most)")
        return PassCriterion(metric, float(bound))

    def metrics(self, value: Any, criteria: tuple[PassCriterion, ...]) -> tuple[str, ...]:
        """``metric:``, one name or a list of them (the first is the headline)."""
        if isinstance(value, list):
            if not value:
                raise self.error("metric: []: expected a metric name or a list of them")
            return tuple(dict.fromkeys(self.metric(v, criteria) for v in value))
        return (self.metric(value, criteria),)

    def metric(self, value: Any, criteria: tuple[PassCriterion, ...]) -> str:
        if value is None:
            numeric = [c.metric for c in criteria if not isinstance(c.bound, bool)]
            return numeric[0] if numeric else DEFAULT_METRIC
        if metric_kind(str(value)) != NUMBER:
            raise self.error(f"metric: {shown(value)}: expected a numeric metric of `cosim "
                             "inspect --json`, e.g. one of "
                             f"{', '.join(k for k in METRIC_KEYS if k not in BOOLEAN_METRICS)}")
        return str(value)


def load_spec(path: str | Path) -> SweepSpec:
    """Read, validate and resolve a sweep spec file (see the module docstring).

    Raises :class:`ConfigError` naming the file, the bad key or value and what was expected.
    """
    from cosim.core.config_fields import to_dict
    from cosim.simulation.scenario_config import load_config

    reader = SpecReader(Path(path))
    data = reader.read()
    scenario, scenario_text = reader.scenario(data)
    tracker = reader.optional_str(data, "tracker")
    estimator = reader.optional_str(data, "estimator")
    duration_s = reader.duration(data.get("duration_s"))
    seeds = reader.seeds(data.get("seeds"))
    where = f"sweep spec {str(path)!r}"
    fixed = tuple((canonical_key(k, where) if isinstance(k, str) else k, v)
                  for k, v in reader.mapping(data, "set").items())
    criteria = reader.criteria(data)
    formulas = reader.formulas(data)
    ray_address = reader.optional_str(data, "ray_address")

    def config(extra: tuple[tuple[str, Any], ...], what: str) -> Any:
        overrides = [override_text(k, v) for k, v in (*fixed, *extra)]
        try:
            return load_config(scenario, None, overrides, seeds[0], duration_s, tracker,
                               estimator)
        except ConfigError as error:
            raise reader.error(f"{what}: {error}") from None

    if formulas:  # every run gets the requirements, after the scenario's own
        existing = [r.formula for r in config((), "config").requirements]
        fixed = (*fixed, ("requirements", [{"formula": f} for f in (*existing, *formulas)]))
        criteria = (*criteria, *(
            PassCriterion(f"stl_robustness_{len(existing) + i}", math.inf, 0.0,
                          label=f"{formula} holds")
            for i, formula in enumerate(formulas)))
    metric, *also_plotted = reader.metrics(data.get("metric"), criteria)
    base = config((), "config")
    leaves = _leaves(to_dict(base))
    if is_plugin_name(base.tracker.name):  # a plug-in's own settings, defaults filled in
        leaves.update(_leaves({"tracker": {"params": resolved_params(base.tracker)}}))

    mode, ranges, random_n, random_seed = reader.sampling(data)
    ranges = {canonical_key(k, where) if isinstance(k, str) else k: v for k, v in ranges.items()}

    fixed_keys = {k for k, _ in fixed} | {
        key for key, given in (("tracker.name", tracker), ("estimator.name", estimator),
                               ("sim.duration_s", duration_s)) if given is not None}
    parameters = [_parameter(reader, mode, key, value, leaves, fixed_keys, config)
                  for key, value in ranges.items()]

    return SweepSpec(
        name=reader.optional_str(data, "name") or Path(path).stem,
        description=reader.description(data),
        scenario=scenario, tracker=tracker, estimator=estimator, duration_s=duration_s,
        seeds=seeds, fixed=fixed, mode=mode, parameters=tuple(parameters),
        random_n=random_n, random_seed=random_seed, criteria=criteria, metric=metric,
        also_plotted=tuple(also_plotted),
        ray_address=ray_address, scenario_text=scenario_text,
        tracker_name=base.tracker.name, estimator_name=base.estimator.name,
        base_mismatch=tuple(row.text() for row in mismatch_table(to_dict(base))),
    )


def _parameter(reader: SpecReader, mode: str, key: Any, value: Any, leaves: dict[str, Any],
               fixed_keys: set[str], config: Callable[..., Any]) -> Parameter:
    """One varied key of ``grid:`` or ``random:`` with its values checked by the config's
    own validation (``config((key, value), where)`` raises naming the value)."""
    where = f"{mode}: {shown(key)}"
    if not isinstance(key, str) or key not in leaves:
        close = difflib.get_close_matches(str(key), list(leaves), n=1)
        hint = f"; did you mean {close[0]}?" if close else ""
        raise reader.error(f"{where}: unknown dotted path: expected a config key such as "
                           f"plant.mass_kg{hint}")
    if key in fixed_keys:
        raise reader.error(f"{where}: also fixed (set:, tracker:, estimator: or "
                           "duration_s:): expected each key either fixed or varied")
    counterpart = _counterpart(key)
    counterpart_value = leaves.get(counterpart) if counterpart else None
    if counterpart not in leaves:
        counterpart = None
    common = {"path": key, "nominal": leaves[key], "counterpart": counterpart,
              "counterpart_value": counterpart_value}
    if mode == "grid":
        if not isinstance(value, list) or not value:
            raise reader.error(f"{where}: {shown(value)}: expected a non-empty list of values")
        for item in value:
            if not isinstance(item, (int, float, str, bool)):
                raise reader.error(f"{where}: {shown(item)}: expected a number, string or "
                                   "boolean")
            config(((key, item),), f"{where} value {shown(item)}")
        if len(set(value)) != len(value):
            raise reader.error(f"{where}: {value}: expected each value once")
        return Parameter(values=tuple(value), **common)
    if not (isinstance(value, list) and len(value) == 2
            and all(_is_number(v) for v in value)):
        raise reader.error(f"{where}: {shown(value)}: expected [low, high] (two numbers)")
    low, high = float(value[0]), float(value[1])
    if low > high:
        raise reader.error(f"{where}: [{value[0]}, {value[1]}]: expected low <= high")
    for end in (low, high):
        config(((key, end),), f"{where} value {end:g}")
    return Parameter(low=low, high=high, **common)


def _counterpart(key: str) -> str | None:
    """The other side of a plant/belief pair (:func:`cosim.simulation.beliefs.counterpart`):
    ``plant.X`` <-> ``tracker.model.X``, ``plant.actuator_delay_s`` <->
    ``tracker.latency_s``, a sensor's noise <-> the filter's belief about it."""
    return counterpart(key)
