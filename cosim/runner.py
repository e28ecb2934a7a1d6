"""The fixed-step multi-rate loop that runs one scenario and logs it to MCAP.

Clock at the physics step (``sim.physics_dt_s``). At each step k, at time t = k dt:

1. log the truth and the estimate (every ``sim.log_period_s``);
2. each sensor whose period is due samples the truth; the estimator fuses it;
3. every ``sim.control_period_s``: the tracker plans from the estimate; its command enters
   the actuator delay line (``plant.actuator_delay_s``);
4. commands that come due leave the delay line, the low-level layer turns them into wheel
   torques (with the controller's belief about the car) and the plant applies them;
5. the plant advances one physics step.

Every period is a whole number of physics steps (checked when the config is loaded). A run
that aborts (diverging physics, an interrupt, an exception) still finishes its MCAP file,
with ``completed: false`` in its metrics.
"""

from __future__ import annotations

import collections
import importlib.metadata
import json
import time
import zlib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from cosim import __version__, foxglove, mcap_schemas
from cosim.config_fields import to_dict
from cosim.exceptions import PhysicsDivergenceError
from cosim.low_level import AccelToTorque
from cosim.metrics import MetricsAccumulator
from cosim.plant import MujocoPlant
from cosim.records import Command
from cosim.recorder import McapRecorder
from cosim.scenario_config import ScenarioConfig, steps_per_period
from cosim.sensors import TruthSensor, make_sensors
from estimation.registry import make_estimator
from tracker.double_lane_change import double_lane_change
from tracker.reference_path import ReferencePath
from tracker.registry import make_tracker


@dataclass(frozen=True)
class RunResult:
    """What a run produced."""

    log_path: Path
    metrics: dict[str, float | int | bool | str]
    completed: bool
    abort_reason: str


def component_rng(seed: int, component: str) -> np.random.Generator:
    """The generator of one component, derived from the run's seed and the component's name.

    Keyed by name (CRC-32), not by position, so adding a sensor leaves every other
    component's random stream unchanged.
    """
    return np.random.default_rng([seed, zlib.crc32(component.encode())])


def build_reference(config: ScenarioConfig) -> ReferencePath:
    """The reference path the scenario names."""
    path = config.path
    if path.kind == "double-lane-change":
        return double_lane_change(path.speed_mps, path.stretch, path.length_m)
    raise AssertionError(f"unhandled path kind {path.kind!r}")  # validated by choices


def _versions() -> dict[str, str]:
    versions = {"cosim": __version__}
    for package in ("mujoco", "dm-control", "casadi", "filterpy", "numpy", "scipy", "mcap"):
        try:
            versions[package] = importlib.metadata.version(package)
        except importlib.metadata.PackageNotFoundError:
            versions[package] = "unknown"
    return versions


def _register_topics(recorder: McapRecorder, sensor_names: list[str]) -> None:
    recorder.register("/vehicle/truth", mcap_schemas.VEHICLE_STATE)
    recorder.register("/vehicle/estimate", mcap_schemas.ESTIMATE)
    recorder.register("/control/command", mcap_schemas.COMMAND)
    recorder.register("/control/plan", mcap_schemas.PLAN)
    recorder.register("/reference/path", mcap_schemas.REFERENCE_PATH)
    recorder.register("/metrics", mcap_schemas.METRICS)
    recorder.register("/tf", mcap_schemas.FRAME_TRANSFORM)
    recorder.register("/scene", mcap_schemas.SCENE_UPDATE)
    recorder.register("/gnss/fix", mcap_schemas.LOCATION_FIX)
    for name in sensor_names:
        recorder.register(f"/sensors/{name}", mcap_schemas.MEASUREMENT)


def run(
    config: ScenarioConfig,
    out_path: Path,
    progress: Callable[[float], None] | None = None,
) -> RunResult:
    """Run one scenario to ``out_path``; ``progress`` is called with the fraction done."""
    wall_start = time.perf_counter()
    sim = config.sim
    dt = sim.physics_dt_s
    n_steps = steps_per_period(sim.duration_s, dt, "sim.duration_s")
    control_steps = steps_per_period(sim.control_period_s, dt, "sim.control_period_s")
    log_steps = steps_per_period(sim.log_period_s, dt, "sim.log_period_s")
    delay_steps = steps_per_period(config.plant.actuator_delay_s, dt, "plant.actuator_delay_s")

    reference = build_reference(config)
    plant = MujocoPlant(config.plant, dt, config.initial)
    estimator = make_estimator(config.estimator, config.initial, config.tracker.model)
    tracker = make_tracker(config.tracker)
    low_level = AccelToTorque(config.tracker.model)
    sensors = make_sensors(config.sensors)
    if "truth" in getattr(estimator, "required_sensors", ()):
        sensors.append(TruthSensor(min(sim.log_period_s, sim.control_period_s)))
    sensor_steps = [
        steps_per_period(s.period_s, dt, f"sensors.{s.name}.period_s") for s in sensors
    ]
    rngs = {s.name: component_rng(config.seed, f"sensors.{s.name}") for s in sensors}
    gnss_sigma_m = config.sensors.gnss.sigma_m

    metrics = MetricsAccumulator(reference)
    delay_line: collections.deque[tuple[int, Command]] = collections.deque()
    completed, abort_reason = False, ""
    result_metrics: dict[str, float | int | bool | str] = {}

    with McapRecorder(out_path) as recorder:
        _register_topics(recorder, [s.name for s in sensors])
        config_dict = to_dict(config)
        recorder.add_metadata("run", {
            "scenario": config.name,
            "seed": str(config.seed),
            "config_yaml": yaml.safe_dump(config_dict, sort_keys=False),
            "config_json": json.dumps(config_dict),
            "versions": json.dumps(_versions()),
            **{f"version_{k}": v for k, v in _versions().items()},
        })
        recorder.add_attachment("sedan.xml", "application/xml", plant.mjcf_xml.encode())
        samples = reference.sample(np.arange(0.0, reference.length_m, 1.0))
        recorder.write("/reference/path", 0.0, {
            **{k: [float(v) for v in samples[k]] for k in samples},
            "speed_mps": reference.speed_mps,
        })
        recorder.write("/scene", 0.0, foxglove.static_scene(
            samples["x_m"], samples["y_m"], config.plant))

        try:
            truth = plant.state()
            latest_speed_mps = config.initial.speed_mps
            for k in range(n_steps + 1):
                t_s = k * dt
                if k % log_steps == 0:
                    estimator.predict(t_s)
                    estimate = estimator.estimate()
                    latest_speed_mps = estimate["vx_mps"]
                    recorder.write_finite("/vehicle/truth", t_s, truth.to_message())
                    recorder.write_finite("/vehicle/estimate", t_s, estimate.to_message())
                    recorder.write("/tf", t_s, foxglove.frame_transform(truth))
                    metrics.add_truth(truth)
                    metrics.add_estimate(estimate, truth)
                for sensor, steps in zip(sensors, sensor_steps):
                    if k % steps:
                        continue
                    measurement = sensor.sample(truth, rngs[sensor.name])
                    recorder.write_finite(f"/sensors/{sensor.name}", t_s,
                                          measurement.to_message())
                    if sensor.name == "gnss":
                        recorder.write("/gnss/fix", t_s, foxglove.location_fix(
                            measurement["x_m"], measurement["y_m"], t_s, gnss_sigma_m,
                            config.geo))
                    update = estimator.update(measurement)
                    if sensor.name != "truth":  # noise-free: NIS is undefined
                        metrics.add_update(update.accepted, update.nis, update.dim,
                                           update.reason != "ignored")
                if k == n_steps:
                    break
                if k % control_steps == 0:
                    estimator.predict(t_s)
                    estimate = estimator.estimate()
                    latest_speed_mps = estimate["vx_mps"]
                    command, plan = tracker.step(t_s, estimate, reference)
                    recorder.write_finite("/control/plan", t_s, plan.to_message())
                    metrics.add_plan(plan)
                    delay_line.append((k + delay_steps, command))
                while delay_line and delay_line[0][0] <= k:
                    _, command = delay_line.popleft()
                    actuator = low_level.convert(command, latest_speed_mps)
                    plant.apply(actuator)
                    metrics.add_command(command)
                    recorder.write("/control/command", t_s, {
                        "t_s": t_s, "accel_mps2": command.accel_mps2,
                        "steer_rad": command.steer_rad,
                        "drive_torque_nm": actuator.drive_torque_nm,
                        "brake_torque_nm": actuator.brake_torque_nm,
                    })
                plant.advance()
                truth = plant.state()
                if progress is not None and k % 500 == 0:
                    progress(k / n_steps)
            completed = True
        except PhysicsDivergenceError as error:
            abort_reason = str(error)
        except KeyboardInterrupt:
            abort_reason = "interrupted"
        except Exception as error:  # the log is finished below, then the error goes on
            abort_reason = f"{type(error).__name__}: {error}"
            _finish(recorder, metrics, wall_start, False, abort_reason)
            raise
        if progress is not None:
            progress(1.0)
        result_metrics = _finish(recorder, metrics, wall_start, completed, abort_reason)
    return RunResult(Path(out_path), result_metrics, completed, abort_reason)


def _finish(recorder: McapRecorder, metrics: MetricsAccumulator, wall_start: float,
            completed: bool, abort_reason: str) -> dict[str, float | int | bool | str]:
    values: dict[str, float | int | bool | str] = dict(
        metrics.result(time.perf_counter() - wall_start, completed))
    if abort_reason:
        values["abort_reason"] = abort_reason
    recorder.write_finite("/metrics", metrics.last_t_s, values)
    recorder.add_metadata("metrics", {"json": json.dumps(
        {k: (v if not isinstance(v, float) or np.isfinite(v) else None)
         for k, v in values.items()})})
    return values
