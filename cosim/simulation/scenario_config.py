"""The whole configuration of a run, and how it is loaded from YAML and overrides.

A scenario is a YAML file (built-in ones live in ``cosim/scenarios/``). Loading merges, in
order: the dataclass defaults, the scenario file, the ``--config`` files (key by key, in the
order given: a car file and a belief file make one configuration), the command-line options
(``--seed``, ``--duration``, ``--tracker``, ``--estimator``) and the ``--set key.path=value``
overrides; then every key and value is validated.
"""

from __future__ import annotations

import copy
import dataclasses
import datetime
import difflib
import importlib.resources
import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from cosim.core.config_fields import (
    from_dict,
    items,
    mapping,
    section,
    set_dotted,
    setting,
    to_dict,
)
from cosim.core.exceptions import ConfigError, RateError
from cosim.core.initial_state import InitialState
from cosim.core.key_aliases import canonical_key, rename_old_keys
from cosim.core.vehicle_params import MOVED_PLANT_KEYS, PlantConfig
from cosim.core.yaml_io import loads as yaml_loads
from cosim.core.yaml_io import read_yaml_file, shown
from cosim.log.foxglove import GeoOrigin
from cosim.plant.disturbances import DisturbanceConfig
from cosim.plant.sedan_sampler import sampled_sedan
from cosim.sensing.faults import FaultConfig
from cosim.sensing.sensors import SensorsConfig, suite_preset
from cosim.simulation.beliefs import take_plant_requests, tell
from cosim.simulation.outcome import OutcomeConfig
from cosim.simulation.path_config import PathConfig
from cosim.simulation.requirements import RequirementConfig, check_requirements
from cosim.simulation.traffic_checks import check_traffic
from cosim.simulation.unread_keys import UnreadKeyWarning, unread_key_warnings
from estimation.config import ESTIMATOR_NAMES, EstimatorConfig
from estimation.noise_config import suite_noise_preset
from estimation.registry import estimator_class, required_sensors
from tracker.config import TrackerConfig, is_plugin_name
from tracker.fmu import check_fmu
from tracker.fmu.config import is_fmu_name
from tracker.manoeuvre import ManoeuvreConfig
from tracker.plugins.loading import check_plugin

DEFAULT_EPOCH = "2026-01-01T00:00:00Z"
"""Log time of sim time 0 unless ``sim.epoch`` says otherwise: a fixed date, so that two
runs with one seed write the same file, and Foxglove shows a date of this era."""


def epoch_ns(text: str) -> int:
    """An ISO 8601 date and time with a zone (``Z`` or ``+hh:mm``) in nanoseconds since
    the Unix epoch; a :class:`ConfigError` naming ``sim.epoch`` otherwise."""
    try:
        moment = datetime.datetime.fromisoformat(text.strip().replace("Z", "+00:00"))
    except ValueError:
        moment = None
    if moment is None or moment.tzinfo is None or moment.year < 1970:
        raise ConfigError(f"sim.epoch = {text!r}: expected an ISO 8601 UTC date and time "
                          "from 1970 on, e.g. 2026-01-01T00:00:00Z")
    delta = moment - datetime.datetime(1970, 1, 1, tzinfo=datetime.timezone.utc)
    return (delta.days * 86_400 + delta.seconds) * 1_000_000_000 + delta.microseconds * 1_000


@dataclass(frozen=True)
class SimConfig:
    """Time base of the run: every period is a whole number of physics steps."""

    physics_dt_s: float = setting(0.002, low=1e-4, high=0.05)
    control_period_s: float = setting(0.05, low=1e-4, high=5.0)
    log_period_s: float = setting(0.01, low=1e-4, high=5.0, doc="truth/estimate log rate")
    scene_period_s: float = setting(
        0.04, low=1e-4, high=5.0,
        doc="period of the Foxglove 3D scenes of the car and the estimate (/scene/car, "
        "/scene/estimate); a whole multiple of log_period_s (25 Hz plays smoothly and "
        "costs a quarter of logging them at the log rate)")
    duration_s: float = setting(15.0, low=0.001, high=3600.0,
                                doc="simulated seconds (a run of 0 s has nothing to show)")
    epoch: str = setting(
        DEFAULT_EPOCH,
        doc="UTC date and time of sim time 0 in the log's timestamps (ISO 8601, e.g. "
        "2026-01-01T00:00:00Z); fixed, so logs stay deterministic")

    def __post_init__(self) -> None:
        epoch_ns(self.epoch)  # refuses a malformed or zone-less date

    @property
    def epoch_ns(self) -> int:
        """:attr:`epoch` in integer nanoseconds since 1970-01-01T00:00:00Z."""
        return epoch_ns(self.epoch)


KMH_SUSPECT_MPS = 50.0
"""A path speed above this (180 km/h) is said in km/h too: 72 meant as km/h runs at 259."""


class UnitHint(UserWarning):
    """A value that looks like it was given in another unit (it is used as given)."""


CAR_NAMES = ("sedan", "ford-escort", "bmw-320i", "vw-vanagon")
"""Values of ``car:`` (:mod:`cosim.cars`)."""


@dataclass(frozen=True)
class ScenarioConfig:
    """Everything a run needs, resolved and validated."""

    name: str = setting("custom")
    description: str = setting("")
    seed: int = setting(0, low=0, high=2**63 - 1)
    vehicle_sample: int = setting(
        -1, low=-1, high=2**31 - 1,
        doc="-1: the nominal sedan; n >= 0: the n-th plausible sedan of "
        "cosim.plant.sedan_sampler (mass, yaw inertia, wheelbase, CoG, tyre stiffness and "
        "friction over published passenger-car ranges) for the plant and the controller's "
        "model alike; keys set explicitly win")
    car: str = setting(
        "sedan", choices=CAR_NAMES,
        doc="sedan: cosim's own mid-size sedan; ford-escort, bmw-320i, vw-vanagon: "
        "CommonRoad's published parameter sets as the plant (cosim/cars/NAME.yaml) with the "
        "belief cosim identify finds for each (NAME-belief.yaml) and tracker weights tuned "
        "for them (published-tuning.yaml); keys set explicitly win")
    sim: SimConfig = section(SimConfig)
    path: PathConfig = section(PathConfig)
    initial: InitialState = section(InitialState)
    plant: PlantConfig = section(PlantConfig)
    sensors: SensorsConfig = section(SensorsConfig)
    faults: tuple[FaultConfig, ...] = items(FaultConfig)
    disturbances: tuple[DisturbanceConfig, ...] = items(DisturbanceConfig)
    estimator: EstimatorConfig = section(EstimatorConfig)
    tracker: TrackerConfig = section(TrackerConfig)
    manoeuvre: ManoeuvreConfig = section(ManoeuvreConfig)
    geo: GeoOrigin = section(GeoOrigin)
    outcome: OutcomeConfig = section(OutcomeConfig)
    traffic: dict[str, Any] = mapping(
        doc="other cars by name (cosim.plant.traffic), e.g. traffic.lead.speed_mps; each "
        "validated as a TrafficCarConfig when the config is loaded")
    requirements: tuple[RequirementConfig, ...] = items(RequirementConfig)
    beliefs_from_plant: dict[str, Any] = mapping(
        doc="the beliefs the controller was told from the plant, belief key -> plant key: "
        "written by the loader for each belief set to `plant` (e.g. tracker.latency_s=plant), "
        "kept in the log, honoured when a shown or logged configuration is loaded again "
        "(cosim.simulation.beliefs)")


def builtin_scenarios() -> dict[str, str]:
    """Built-in scenario names and their one-line descriptions."""
    scenarios = {}
    for entry in sorted(importlib.resources.files("cosim.scenarios").iterdir(),
                        key=lambda e: e.name):
        if entry.name.endswith(".yaml"):
            data = yaml_loads(entry.read_text()) or {}
            scenarios[entry.name.removesuffix(".yaml")] = str(data.get("description", ""))
    return scenarios


def _read_yaml(path: Path, what: str) -> dict[str, Any]:
    data = read_yaml_file(path, what)
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError(f"{what} {str(path)!r}: expected a mapping of keys to values")
    return data


def _scenario_data(scenario: str) -> dict[str, Any]:
    builtin = importlib.resources.files("cosim.scenarios") / f"{scenario}.yaml"
    if builtin.is_file():
        data = yaml_loads(builtin.read_text()) or {}
        data.setdefault("name", scenario)
        return data
    path = Path(scenario)
    if path.suffix in (".yaml", ".yml") or path.exists():
        data = _read_yaml(path, "scenario")
        data.setdefault("name", path.stem)
        return data
    names = builtin_scenarios()
    close = difflib.get_close_matches(scenario.replace("_", "-").lower(), list(names), n=1,
                                      cutoff=0.6)
    if close:
        raise ConfigError(f"scenario {scenario!r}: did you mean {close[0]!r}? (every "
                          "scenario: `cosim scenarios`)")
    known = ", ".join(names)
    raise ConfigError(
        f"scenario {scenario!r}: expected a built-in name ({known}) or a YAML file path"
    )


class ConfigMergeNote(UserWarning):
    """Two ``--config`` files set one key: the later one's value is used."""


def config_files(config_file: str | Sequence[str] | None) -> list[str]:
    """``--config`` as a list of files, in the order given (None: none)."""
    if config_file is None:
        return []
    return [config_file] if isinstance(config_file, str) else list(config_file)


def _config_file_data(path: str) -> dict[str, Any]:
    return rename_old_keys(_read_yaml(Path(path), "--config"), "--config")


def _leaf_keys(data: Any, prefix: str = "") -> list[str]:
    """The dotted keys of a nested mapping's leaves (a list is one leaf)."""
    if not isinstance(data, dict):
        return [prefix]
    keys: list[str] = []
    for key, value in data.items():
        keys += _leaf_keys(value, f"{prefix}.{key}" if prefix else str(key))
    return keys


def config_sources(config_file: str | Sequence[str] | None) -> dict[str, str]:
    """Which ``--config`` file set each dotted key (the last that set it), for
    ``cosim config show``."""
    sources: dict[str, str] = {}
    for path in config_files(config_file):
        for key in _leaf_keys(_config_file_data(path)):
            sources[key] = path
    return sources


def _note_keys_set_twice(files: Sequence[str]) -> None:
    """One note naming the keys more than one ``--config`` file sets, and which file won."""
    setters: dict[str, list[str]] = {}
    for path in files:
        for key in _leaf_keys(_config_file_data(path)):
            setters.setdefault(key, []).append(path)
    twice = {key: paths for key, paths in setters.items() if len(paths) > 1}
    if twice:
        shown_keys = "; ".join(f"{key} by {' and '.join(paths)} ({paths[-1]} wins)"
                               for key, paths in twice.items())
        warnings.warn(f"--config: {len(twice)} key(s) set by more than one file, the later "
                      f"file's value used: {shown_keys}", ConfigMergeNote, stacklevel=3)


def _merge(base: dict[str, Any], top: dict[str, Any]) -> dict[str, Any]:
    merged = copy.deepcopy(base)
    for key, value in top.items():
        if isinstance(value, dict) and isinstance(merged.get(key), dict):
            merged[key] = _merge(merged[key], value)
        else:
            merged[key] = copy.deepcopy(value)
    return merged


def parse_override(text: str) -> tuple[str, Any]:
    """``'tracker.horizon=30'`` -> ``('tracker.horizon', 30)``; the value is parsed as YAML."""
    key, sep, raw = text.partition("=")
    if not sep or not key.strip():
        raise ConfigError(f"--set {text!r}: expected key.path=value")
    try:
        value = yaml_loads(raw) if raw.strip() else ""
    except yaml.YAMLError:
        value = raw
    except ConfigError as error:
        raise ConfigError(f"--set {shown(text)}: {error}") from None
    return key.strip(), value


def load_config(
    scenario: str,
    config_file: str | Sequence[str] | None = None,
    overrides: list[str] | tuple[str, ...] = (),
    seed: int | None = None,
    duration_s: float | None = None,
    tracker: str | None = None,
    estimator: str | None = None,
) -> ScenarioConfig:
    """Resolve a scenario name or path plus overrides into a validated configuration.

    ``config_file`` is one ``--config`` file or several, merged over the scenario in order,
    key by key (a later file wins a key both set, as a later ``--set`` does); a key set by
    two files is said in one :class:`ConfigMergeNote`."""
    data = rename_old_keys(_scenario_data(scenario), f"scenario {scenario}")
    files = config_files(config_file)
    for path in files:
        data = _merge(data, _config_file_data(path))
    if len(files) > 1:
        _note_keys_set_twice(files)
    if seed is not None:
        data["seed"] = seed
    if duration_s is not None:
        set_dotted(data, "sim.duration_s", duration_s)
    if tracker is not None:
        set_dotted(data, "tracker.name", tracker)
    if estimator is not None:
        set_dotted(data, "estimator.name", estimator)
    for text in overrides:
        key, value = parse_override(text)
        set_dotted(data, canonical_key(key, "--set"), value)
    rename_old_keys(data, "--set")  # an old key inside a mapping given as a --set value
    data = _with_sampled_vehicle(data)
    data = _with_car(data)
    sensors = data.get("sensors")
    if isinstance(sensors, dict) and isinstance(sensors.get("suite"), str):
        # The suite presets figures; what the user set explicitly wins.
        data["sensors"] = _merge(suite_preset(sensors["suite"]), sensors)
        _believe_suite(data, sensors["suite"])
    requests = take_plant_requests(data)  # `plant` beliefs: the controller is told
    _refuse_moved_keys(data)
    config = tell(from_dict(ScenarioConfig, data), requests)
    for line in unread_key_warnings(data, config.tracker.name, config.plant.tyre_model,
                                    config.initial.speed_from_profile,
                                    to_dict(ScenarioConfig())):
        warnings.warn(line, UnreadKeyWarning, stacklevel=2)
    if config.path.speed_mps > KMH_SUSPECT_MPS:
        warnings.warn(f"path.speed_mps = {config.path.speed_mps:g} m/s is "
                      f"{config.path.speed_mps * 3.6:.0f} km/h; if {config.path.speed_mps:g} "
                      f"km/h was meant, that is {config.path.speed_mps / 3.6:.3g} m/s",
                      UnitHint, stacklevel=2)
    check_rates(config)
    check_latency(config)
    check_requirements(config.requirements, config.sim.log_period_s)
    check_required_sensors(config)
    check_faults(config)
    check_traffic(config)  # a bad car, or one the ego or its ACC cannot meet: here
    # A bad plug-in or FMU is refused here, before any run starts.
    if is_plugin_name(config.tracker.name):
        check_plugin(config.tracker)
    if is_fmu_name(config.tracker.name):
        check_fmu(config.tracker, config.sim.control_period_s,
                  getattr(estimator_class(config.estimator.name), "state_names", None))
    elif config.tracker.fmu.parameters:
        warnings.warn(f"tracker.fmu.parameters is set but tracker.name = "
                      f"{config.tracker.name!r} is no FMU: ignored", stacklevel=2)
    if config.estimator.name not in ESTIMATOR_NAMES:
        estimator_class(config.estimator.name)
    return config


def _with_car(data: dict[str, Any]) -> dict[str, Any]:
    """``car: NAME``: the published car's plant, its identified belief and the tracker
    weights tuned for the published cars (``cosim/cars/published-tuning.yaml``) under what
    was set (a bad name is left to from_dict, which names the choices)."""
    name = data.get("car", "sedan")
    if name == "sedan" or name not in CAR_NAMES:
        return data
    folder = importlib.resources.files("cosim.cars")
    car: dict[str, Any] = {}
    for part in (f"{name}.yaml", f"{name}-belief.yaml", "published-tuning.yaml"):
        car = _merge(car, yaml_loads((folder / part).read_text()) or {})
    return _merge(car, data)


def _with_sampled_vehicle(data: dict[str, Any]) -> dict[str, Any]:
    """``vehicle_sample: n >= 0``: the sampled sedan's figures under what was set. With a
    published ``car:`` too it is refused: the two would make a car neither is (the sample's
    mass and CoG on the published car's tracks and tyres, its filter's beliefs of neither)."""
    index = data.get("vehicle_sample", -1)
    if isinstance(index, bool) or not isinstance(index, int) or index < 0:
        return data  # -1, or a bad value that from_dict names
    car = data.get("car", "sedan")
    if car != "sedan":
        raise ConfigError(f"vehicle_sample = {index} with car = {car!r}: a sampled car is a "
                          "sedan of its own; expected one of them (vehicle_sample -1, or "
                          "car sedan)")
    return _merge(sampled_sedan(index), data)


def _refuse_moved_keys(data: dict[str, Any]) -> None:
    """A key that moved (:data:`cosim.core.vehicle_params.MOVED_PLANT_KEYS`) is refused
    with its new name: a silent move would change what an old scenario means."""
    plant = data.get("plant")
    if not isinstance(plant, dict):
        return
    for key, new in MOVED_PLANT_KEYS.items():
        if key in plant:
            raise ConfigError(
                f"plant.{key}: the plant does not read it (its tyres are the Magic Formula "
                f"of plant.tyre.*); the controller's belief is {new}")


def check_faults(config: ScenarioConfig) -> None:
    """Refuse a fault on a sensor the run does not have (it would silently do nothing)."""
    for index, fault in enumerate(config.faults):
        if not getattr(config.sensors, fault.sensor).enabled:
            raise ConfigError(
                f"faults[{index}].sensor = {fault.sensor!r}: that sensor is disabled "
                f"(sensors.{fault.sensor}.enabled = false): expected an enabled sensor")


def _believe_suite(data: dict[str, Any], suite: str) -> None:
    """The estimator believes the chosen suite's datasheet (``estimator.noise``,
    :func:`estimation.noise_config.suite_noise_preset`), so a plain run is matched; a
    belief figure set explicitly wins, which is how a study makes the belief wrong."""
    preset = suite_noise_preset(suite)
    if not preset:
        return
    estimator = data.setdefault("estimator", {})
    if not isinstance(estimator, dict):
        return  # from_dict names the bad value
    noise = estimator.get("noise")
    if noise is None:
        noise = {}
    if isinstance(noise, dict):
        estimator["noise"] = _merge(preset, noise)


def check_required_sensors(config: ScenarioConfig) -> None:
    """Refuse a run whose estimator needs a sensor that is disabled (one line, exit 2)."""
    for name in required_sensors(config.estimator.name):
        sensor = getattr(config.sensors, name, None)
        if sensor is not None and not sensor.enabled:
            raise ConfigError(
                f"sensors.{name}.enabled = false: estimator.name = {config.estimator.name} "
                f"needs the {name} sensor (enable it or choose another estimator)"
            )


def steps_per_period(period_s: float, physics_dt_s: float, key: str,
                     base_key: str = "sim.physics_dt_s") -> int:
    """Whole physics steps in ``period_s``; a period that is not a whole multiple is refused.
    (``base_key`` names the base period in the message when it is not the physics step.)

    Like dm_control's ``compute_n_steps``: rounding a rate silently would change the
    experiment, so it is an error.
    """
    ratio = period_s / physics_dt_s
    steps = round(ratio)
    if abs(ratio - steps) > 1e-6 * max(1.0, ratio):
        below = max(math.floor(ratio), 1) * physics_dt_s
        above = max(math.ceil(ratio), 2) * physics_dt_s
        raise RateError(
            f"{key} = {period_s:g}: expected a whole multiple of {base_key} = "
            f"{physics_dt_s:g} (e.g. {below:g} or {above:g})"
        )
    return steps


def check_latency(config: ScenarioConfig) -> None:
    """A sensor latency is a whole number of physics steps; one longer than the filter's
    history (``estimator.history_s``) says that the filter will reject those fixes."""
    latency_s = config.sensors.gnss.latency_s
    steps_per_period(latency_s, config.sim.physics_dt_s, "sensors.gnss.latency_s")
    if (config.sensors.gnss.enabled and config.estimator.name in ("ekf", "ukf")
            and latency_s > config.estimator.history_s):
        warnings.warn(f"sensors.gnss.latency_s = {latency_s:g} s but estimator.history_s = "
                      f"{config.estimator.history_s:g} s: the filter rejects every fix as "
                      f"stale (set estimator.history_s >= {latency_s:g} to fuse them at their "
                      "own time)", stacklevel=3)


def check_rates(config: ScenarioConfig) -> None:
    """Refuse every period that is not a whole, positive number of physics steps."""
    dt = config.sim.physics_dt_s
    periods = {
        "sim.control_period_s": config.sim.control_period_s,
        "sim.log_period_s": config.sim.log_period_s,
    }
    for field in dataclasses.fields(config.sensors):
        sensor = getattr(config.sensors, field.name)
        if hasattr(sensor, "period_s"):
            periods[f"sensors.{field.name}.period_s"] = sensor.period_s
    for key, period in periods.items():
        if steps_per_period(period, dt, key) < 1:
            raise RateError(f"{key} = {period:g}: expected at least sim.physics_dt_s = {dt:g}")
    steps_per_period(config.plant.actuator_delay_s, dt, "plant.actuator_delay_s")
    steps_per_period(config.sim.duration_s, dt, "sim.duration_s")
    steps_per_period(config.sim.scene_period_s, config.sim.log_period_s, "sim.scene_period_s",
                     "sim.log_period_s")
