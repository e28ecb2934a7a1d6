"""Monte Carlo consistency of the Kalman filters in the closed loop (measures and prints).

    .venv/bin/python bench/estimator_consistency.py [--seeds 20] [--estimators ekf ukf]
        [--suite gnss] [--duration 15] [--workers 2] [--set key=value ...]

Runs the lane change once per seed (seeds 0 .. N-1) with each estimator, the real plant and
the real runner, and prints per estimator the 95 % chi-square band of the average NEES over
the runs (4 DoF: x, y, yaw, vx; :mod:`estimation.consistency`), the average of the runs'
``nees_mean``, and the RMSEs of position, yaw and speed over all runs. Then the cost of
each estimator: the sensor log of seed 0's run is replayed into a fresh estimator, and the
median time of a prediction over one 10 ms step and of an update per sensor is printed.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from cosim.log.reader import iter_messages
from cosim.records import Measurement
from cosim.simulation.runner import run
from cosim.simulation.scenario_config import ScenarioConfig, load_config
from estimation.consistency import summarise
from estimation.registry import make_estimator

_KEYS = ("nees_mean", "nis_mean", "est_pos_rmse_m", "est_yaw_rmse_rad", "est_speed_rmse_mps",
         "cte_rms_m", "rejected_measurements", "channels_gated", "completed")


def _one_run(task: tuple[str, int, str, float | None, tuple[str, ...], str]) -> dict[str, object]:
    scenario, seed, estimator, duration_s, overrides, out_dir = task
    config = load_config(scenario, overrides=list(overrides), seed=seed, duration_s=duration_s,
                         estimator=estimator)
    path = Path(out_dir) / f"{estimator}-{seed}.mcap"
    result = run(config, path)
    path.unlink()
    return {key: result.metrics[key] for key in _KEYS if key in result.metrics}


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
    sensors = ["gnss", "imu", "wheel_speed", "steering"]
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--estimators", nargs="+", default=["ekf", "ukf"])
    parser.add_argument("--suite", default="gnss")
    parser.add_argument("--scenario", default="lane-change")
    parser.add_argument("--duration", type=float, default=None, help="s (default: scenario's)")
    parser.add_argument("--workers", type=int, default=min(4, os.cpu_count() or 1))
    parser.add_argument("--set", action="append", default=[], dest="overrides")
    parser.add_argument("--verbose", action="store_true", help="print every run")
    args = parser.parse_args()
    if args.seeds < 1:
        parser.error("--seeds: expected at least 1")
    overrides = (f"sensors.suite={args.suite}", *args.overrides)
    print(f"{args.scenario}, sensors.suite={args.suite}, seeds 0..{args.seeds - 1}"
          + (f", {' '.join(args.overrides)}" if args.overrides else ""))
    with tempfile.TemporaryDirectory() as tmp, ProcessPoolExecutor(args.workers) as pool:
        for estimator in args.estimators:
            tasks = [(args.scenario, seed, estimator, args.duration, overrides, tmp)
                     for seed in range(args.seeds)]
            metrics = list(pool.map(_one_run, tasks))
            if args.verbose:
                for seed, m in enumerate(metrics):
                    print(f"  seed {seed:3d} " + "  ".join(
                        f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}"
                        for k, v in m.items()))
            failed = [seed for seed, m in enumerate(metrics) if not m.get("completed")]
            if failed:
                print(f"{estimator}: runs of seeds {failed} did not complete")
            for line in summarise(estimator, metrics).lines():
                print(line)
        config = load_config(args.scenario, overrides=list(overrides), seed=0,
                             duration_s=args.duration)
        log = Path(tmp) / "costs.mcap"
        run(config, log)
        print("cost per call, median over a replay of seed 0's sensor log [us]:")
        for estimator in args.estimators:
            if estimator == "truth":
                continue
            costs = _costs(config, log, estimator)
            print(f"  {estimator}: " + ", ".join(f"{k} {v:.0f}" for k, v in costs.items()))


if __name__ == "__main__":
    main()
