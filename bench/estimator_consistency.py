"""Monte Carlo consistency of the Kalman filters in the closed loop (measures and prints).

    .venv/bin/python bench/estimator_consistency.py [--suites rtk gnss] [--estimators ekf ukf]
        [--seeds 20] [--first-seed 100] [--duration 15] [--workers 2] [--set key=value ...]
        [--costs]

Runs the lane change once per seed with each suite and estimator, the real plant and the real
runner, and prints for each the consistency figures of Bar-Shalom, Li, Kirubarajan (2001),
section 5.4 (:mod:`estimation.consistency`): the ANEES over the runs at every logged time
step after the first second with its 95 % chi-square band (N runs x 4 dof: x, y, yaw, vx),
the fraction of steps inside (and below, above), the NIS per degree of freedom of every
sensor (gated updates included), and the RMSEs of position, yaw and speed and the tracking
figures over the runs. ``--costs`` adds the cost of each estimator: the sensor log of one
run is replayed into a fresh estimator, and the median time of a prediction over one 10 ms
step and of an update per sensor is printed.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import statistics
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from cosim.core.records import Measurement
from cosim.log.reader import iter_messages
from cosim.simulation.runner import run
from cosim.simulation.scenario_config import ScenarioConfig, load_config
from cosim.sweeps.ensemble import EnsembleMember, judge, run_member
from estimation.registry import make_estimator

_FIGURES = ("est_pos_rmse_m", "est_yaw_rmse_rad", "est_speed_rmse_mps", "cte_max_m",
            "nees_mean", "rejected_measurements", "channels_gated")


def _config(scenario: str, suite: str, estimator: str, duration_s: float | None,
            overrides: tuple[str, ...]) -> ScenarioConfig:
    return load_config(scenario, overrides=[f"sensors.suite={suite}", *overrides],
                       duration_s=duration_s, estimator=estimator)


def _one_run(task: tuple[str, str, str, float | None, tuple[str, ...], int, str]
             ) -> EnsembleMember:
    scenario, suite, estimator, duration_s, overrides, seed, out_dir = task
    config = _config(scenario, suite, estimator, duration_s, overrides)
    return run_member(config, seed, Path(out_dir))


def _logged_measurements(path: Path, sensors: list[str]) -> list[Measurement]:
    """The measurements a run fused, rebuilt from its log (diagonal covariance from the
    logged sigmas; null values back to NaN), in time order (sensor order on ties)."""
    measurements = []
    for order, sensor in enumerate(sensors):
        for _, message in iter_messages(path, f"/sensors/{sensor}"):
            names = tuple(k for k in message if k not in ("t_s", "sensor", "sigma"))
            values = np.array([np.nan if message[n] is None else message[n] for n in names])
            covariance = np.diag(np.square(message["sigma"]))
            measurements.append((message["t_s"], order,
                                 Measurement(sensor, message["t_s"], names, values, covariance)))
    measurements.sort(key=lambda item: (item[0], item[1]))
    return [m for _, _, m in measurements]


def _costs(config: ScenarioConfig, log: Path, estimator: str) -> dict[str, float]:
    """Median microseconds of one prediction step and of an update per sensor."""
    sensors = ["gnss", "gnss_velocity", "heading", "imu", "wheel_speed", "steering"]
    measurements = _logged_measurements(log, sensors)
    filter_ = make_estimator(dataclasses.replace(config.estimator, name=estimator),
                             config.initial, config.tracker.model)
    times: dict[str, list[float]] = {}
    for measurement in measurements:
        if measurement.t_s > filter_.t_s:
            start = time.perf_counter()
            filter_.predict(measurement.t_s)
            times.setdefault("predict 10 ms", []).append(time.perf_counter() - start)
        start = time.perf_counter()
        filter_.update(measurement)
        times.setdefault(f"update {measurement.sensor}", []).append(time.perf_counter() - start)
    return {key: 1e6 * statistics.median(values) for key, values in times.items()}


def _rms(values: list[float]) -> float:
    return math.sqrt(float(np.mean(np.square(values))))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--suites", nargs="+", default=["rtk", "gnss"])
    parser.add_argument("--estimators", nargs="+", default=["ekf", "ukf"])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--first-seed", type=int, default=100,
                        help="seeds first .. first + N - 1 (default 100: seeds no test uses)")
    parser.add_argument("--scenario", default="lane-change")
    parser.add_argument("--duration", type=float, default=None, help="s (default: scenario's)")
    parser.add_argument("--workers", type=int, default=min(2, os.cpu_count() or 1))
    parser.add_argument("--set", action="append", default=[], dest="overrides")
    parser.add_argument("--verbose", action="store_true", help="print every run")
    parser.add_argument("--costs", action="store_true", help="also time the estimators")
    args = parser.parse_args()
    if args.seeds < 1:
        parser.error("--seeds: expected at least 1")
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    overrides = tuple(args.overrides)
    print(f"{args.scenario}, seeds {seeds.start}..{seeds.stop - 1}"
          + (f", {' '.join(overrides)}" if overrides else ""))
    with tempfile.TemporaryDirectory() as tmp, ProcessPoolExecutor(args.workers) as pool:
        for suite in args.suites:
            for estimator in args.estimators:
                tasks = [(args.scenario, suite, estimator, args.duration, overrides, seed, tmp)
                         for seed in seeds]
                members = list(pool.map(_one_run, tasks))
                print(f"\n{suite} / {estimator}: {len(members)} runs")
                if args.verbose:
                    for m in members:
                        print(f"  seed {m.seed:4d} " + "  ".join(
                            f"{k} {float(m.metrics[k]):.4g}" for k in _FIGURES
                            if k in m.metrics))
                for line in judge(members).lines():
                    print("  " + line)
                for key in _FIGURES[:3]:
                    values = [float(m.metrics[key]) for m in members]  # type: ignore[arg-type]
                    print(f"  {key:22s} RMS over runs {_rms(values):.4f}")
                ctes = [float(m.metrics["cte_max_m"]) for m in members]
                print(f"  cte_max_m              max over runs {max(ctes):.4f}, median "
                      f"{statistics.median(ctes):.4f}")
        if args.costs:
            config = _config(args.scenario, args.suites[0], args.estimators[0], args.duration,
                             overrides)
            log = Path(tmp) / "costs.mcap"
            run(config, log)
            print("cost per call, median over a replay of one run's sensor log [us]:")
            for estimator in args.estimators:
                if estimator == "truth":
                    continue
                costs = _costs(config, log, estimator)
                print(f"  {estimator}: " + ", ".join(f"{k} {v:.0f}" for k, v in costs.items()))


if __name__ == "__main__":
    main()
