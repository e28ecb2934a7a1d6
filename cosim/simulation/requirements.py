"""Requirements in Signal Temporal Logic over a run's signals, and their robustness.

A requirement is an STL formula over the signals of :data:`SIGNALS` (sampled at the log
period, ``sim.log_period_s``), e.g.::

    always (abs(cte_m) <= 0.3)
    always ((t > 9) -> eventually[0,2] (abs(heading_err_rad) <= 0.02))

Time bounds are in seconds. The formula is evaluated offline at the end of the run by
``rtamt`` (Nickovic and Yamaguchi, "RTAMT: Online Robustness Monitors from STL", ATVA 2020;
discrete-time semantics at the log period), which gives its *robustness* at t = 0: how far
the run is from violating it, in the unit of the predicates (metres for the first formula:
``0.3 - max |cte|``). Positive or zero: the run satisfies it; negative: it violates it, by
that much (Donze and Maler, "Robust Satisfaction of Temporal Logic over Real-Valued
Signals", FORMATS 2010). A robustness is a continuous objective, so it can be searched for
its zero (``cosim envelope``) as a pass/fail cannot.

Syntax (rtamt's STL): ``always``, ``eventually``, each with an optional ``[a,b]`` bound in
seconds; ``until``; ``not``, ``and``, ``or``, ``->``; comparisons ``<``, ``<=``, ``>``, ``>=``,
``==``; arithmetic ``+ - * /`` and ``abs(...)``. A formula naming an unknown signal, or one
that does not parse, is refused in one line before any run.

A run's requirements are its configuration's ``requirements:`` (each ``{formula: ...}``);
``cosim run --require``, a sweep's ``pass: {stl: ...}`` and ``--fail-if`` with a formula add
them. Metrics: ``stl_robustness_<i>`` per requirement (from 0, in order) and
``stl_robustness``, the smallest of them.
"""

from __future__ import annotations

import contextlib
import logging
import math
import re
import warnings
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from cosim.core.config_fields import setting
from cosim.core.exceptions import ConfigError
from cosim.core.yaml_io import shown

SIGNALS: Mapping[str, str] = {
    "t": "simulated time [s]",
    "cte_m": "cross-track error of the true centre of gravity, left of the path positive [m]",
    "heading_err_rad": "true heading minus the path's heading at the projection [rad]",
    "speed_err_mps": "true speed minus the reference speed [m/s]",
    "speed_mps": "true horizontal speed of the centre of gravity [m/s]",
    "ref_speed_mps": "the reference speed at the projection [m/s]",
    "lat_accel_mps2": "true lateral acceleration, vehicle frame [m/s^2]",
    "yaw_rate_radps": "true yaw rate [rad/s]",
    "steer_rad": "true road-wheel steering angle, left positive [rad]",
}
"""Every signal a formula may name, with its meaning and unit (at the log period)."""


TEMPORAL = re.compile(r"\b(always|eventually|until|historically|once|since|next|prev)\b")
"""The temporal operators; a formula with none would judge the first instant only."""


@dataclass(frozen=True)
class RequirementConfig:
    """One STL requirement of a run (:mod:`cosim.simulation.requirements`)."""

    formula: str = setting("", doc="an STL formula over the run's signals "
                           "(cosim.simulation.requirements), e.g. always (abs(cte_m) <= 0.3)")


@contextlib.contextmanager
def _quiet() -> Iterator[None]:
    """rtamt warns through the root logger; its errors are what cosim reports."""
    previous = logging.root.manager.disable
    logging.disable(logging.WARNING)
    try:
        yield
    finally:
        logging.disable(previous)


def _specification(formula: str, period_s: float) -> Any:
    with warnings.catch_warnings():  # its ANTLR runtime imports typing.io (deprecated)
        warnings.simplefilter("ignore", DeprecationWarning)
        import rtamt

    spec = rtamt.StlDiscreteTimeOfflineSpecification()
    for name in SIGNALS:
        spec.declare_var(name, "float")
    spec.set_sampling_period(round(period_s * 1e6), "us", 0.1)
    spec.spec = formula
    with _quiet():
        spec.parse()
    return spec


def check_formula(formula: str, where: str, period_s: float = 0.01) -> None:
    """Parse ``formula``; refuse it in one line naming ``where`` (a key, or an option such
    as ``--require``) when it names an unknown signal or does not parse."""
    where = where if where.startswith("--") else f"{where} ="
    if not isinstance(formula, str) or not formula.strip():
        raise ConfigError(f"{where} {shown(formula)}: expected an STL formula over "
                          f"{', '.join(SIGNALS)} (e.g. always (abs(cte_m) <= 0.3))")
    if not TEMPORAL.search(formula):
        raise ConfigError(f"{where} {shown(formula)}: no temporal operator, so it judges "
                          "t = 0 alone: expected always (...) or eventually (...) around it")
    try:
        _specification(formula, period_s)
    except ImportError:
        raise ConfigError(f"{where.removesuffix(' =')}: STL requirements need the rtamt "
                          "package (pip install rtamt; Python < 3.13)") from None
    except KeyError as error:
        raise ConfigError(f"{where} {shown(formula)}: unknown signal {error.args[0]!r}: "
                          f"expected one of {', '.join(SIGNALS)}") from None
    except Exception as error:  # noqa: BLE001 - rtamt's parse errors have no common type
        text = " ".join(str(error).split()).removeprefix("RTAMT Exception: ")
        text = text.split(" expecting ")[0]
        if len(text) > 160:
            text = text[:157] + "..."
        raise ConfigError(f"{where} {shown(formula)}: not STL ({text}); expected e.g. "
                          "always (abs(cte_m) <= 0.3)") from None


def check_requirements(requirements: Sequence[RequirementConfig], period_s: float) -> None:
    """Every requirement of a configuration parsed (one line for the first bad one)."""
    for index, requirement in enumerate(requirements):
        check_formula(requirement.formula, f"requirements[{index}].formula", period_s)


@dataclass
class SignalTrace:
    """The signals of :data:`SIGNALS` at each log instant of a run."""

    samples: dict[str, list[float]] = field(
        default_factory=lambda: {name: [] for name in SIGNALS})

    def add(self, values: Mapping[str, float]) -> None:
        """One log instant: a value for every signal."""
        for name, column in self.samples.items():
            column.append(float(values[name]))

    def __len__(self) -> int:
        return len(self.samples["t"])


def robustness(formula: str, trace: SignalTrace, period_s: float) -> float:
    """The robustness of ``formula`` at the trace's first instant (NaN for an empty trace
    or a non-finite signal value)."""
    if len(trace) == 0:
        return math.nan
    dataset: dict[str, list[float]] = {"time": trace.samples["t"]}
    dataset.update(trace.samples)
    if not all(math.isfinite(v) for column in trace.samples.values() for v in column):
        return math.nan
    spec = _specification(formula, period_s)
    with _quiet():
        result = spec.evaluate(dataset)
    return float(result[0][1])


def requirement_metrics(requirements: Sequence[RequirementConfig], trace: SignalTrace | None,
                        period_s: float) -> dict[str, float]:
    """``stl_robustness_<i>`` per requirement and ``stl_robustness`` (the smallest; NaN if
    any is): none for a run without requirements."""
    if not requirements or trace is None:
        return {}
    values = {f"stl_robustness_{i}": robustness(r.formula, trace, period_s)
              for i, r in enumerate(requirements)}
    worst = min(values.values())
    values["stl_robustness"] = math.nan if any(math.isnan(v) for v in values.values()) \
        else worst
    return values


def trace_from_messages(errors: Sequence[Mapping[str, Any]],
                        truths: Sequence[Mapping[str, Any]]) -> SignalTrace:
    """The trace of a log: its ``/control/errors`` and ``/vehicle/truth`` messages (the
    same instants, in order), as the run built it."""
    trace = SignalTrace()
    for error, truth in zip(errors, truths, strict=False):
        trace.add(signal_values(error, truth))
    return trace


def signal_values(errors: Mapping[str, Any], truth: Mapping[str, Any]) -> dict[str, float]:
    """The signals at one instant from the tracking errors (``/control/errors``' fields) and
    the truth (:class:`~cosim.core.records.VehicleState`'s message fields)."""
    return {
        "t": errors["t_s"], "cte_m": errors["cte_m"],
        "heading_err_rad": errors["heading_err_rad"],
        "speed_err_mps": errors["speed_err_mps"], "speed_mps": errors["speed_mps"],
        "ref_speed_mps": errors["ref_speed_mps"], "lat_accel_mps2": truth["ay_mps2"],
        "yaw_rate_radps": truth["yaw_rate_radps"], "steer_rad": truth["steer_rad"],
    }


def with_requirements(config: Any, formulas: Sequence[str], where: str) -> tuple[Any, int]:
    """``config`` (a :class:`~cosim.simulation.scenario_config.ScenarioConfig`) with
    ``formulas`` appended to its requirements (each checked, named by ``where``), and the
    index of the first appended one."""
    import dataclasses

    for formula in formulas:
        check_formula(formula, where, config.sim.log_period_s)
    first = len(config.requirements)
    added = tuple(RequirementConfig(formula) for formula in formulas)
    return dataclasses.replace(config, requirements=config.requirements + added), first
