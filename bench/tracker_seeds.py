"""Every MPC tracker on the lane change over several seeds, against the delta-u MPC's bar.

    .venv/bin/python bench/tracker_seeds.py [--seeds 5] [--tracker NAME ...] [--set k=v ...]

The bar for a delta-u MPC on this path (Rajamani's path-error model, see
:mod:`tracker.mpc.dynamic_mpc`), on its own linear model without noise: max lateral deviation 88 mm,
heading error under 3 deg, 20 m/s reached by 5.8 s, steering within 15 deg, acceleration
within 3 m/s^2. Here each tracker drives the MuJoCo sedan with the ``rtk`` suite and the EKF
(the ``lane-change`` scenario) once per seed; the table prints one row per run and the worst
case per tracker. Accuracy figures are deterministic per seed; solve times are this
machine's, measured in this invocation (runs go one after another, never in parallel).
"""

from __future__ import annotations

import argparse
import math
import tempfile
from pathlib import Path

from cosim.core.exceptions import CosimError
from cosim.log import topics
from cosim.log.reader import iter_messages
from cosim.simulation.runner import run
from cosim.simulation.scenario_config import load_config

DEFAULT_TRACKERS: tuple[str, ...] = ("dynamic-nmpc", "ltv-mpc", "dynamic-mpc", "kinematic-nmpc")


def _time_to_speed_s(log_path: Path, speed_mps: float) -> float:
    """First time the true forward speed reaches ``speed_mps`` (nan if never)."""
    for _, message in iter_messages(log_path, topics.VEHICLE_TRUTH):
        if message["vx_mps"] >= speed_mps:
            return float(message["t_s"])
    return math.nan


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--tracker", action="append", dest="trackers")
    parser.add_argument("--set", action="append", default=[], dest="overrides")
    args = parser.parse_args()
    trackers = tuple(args.trackers or DEFAULT_TRACKERS)
    header = (f"{'tracker':<15}{'seed':>5}{'cte_max_m':>11}{'head_deg':>10}{'steer_deg':>10}"
              f"{'accel':>14}{'t20_s':>7}{'p50_ms':>8}{'p99_ms':>8}{'fail':>6}")
    print(header)
    with tempfile.TemporaryDirectory() as tmp:
        for tracker in trackers:
            worst = 0.0
            for seed in range(args.seeds):
                try:
                    config = load_config("lane-change", overrides=args.overrides, seed=seed,
                                         tracker=tracker)
                except CosimError as error:
                    print(f"{tracker:<15} skipped: {error}")
                    break
                log_path = Path(tmp) / f"{tracker}-{seed}.mcap"
                m = run(config, log_path).metrics
                worst = max(worst, m["cte_max_m"])
                accel = f"[{m['accel_min_mps2']:+.2f},{m['accel_max_mps2']:+.2f}]"
                print(f"{tracker:<15}{seed:>5}{m['cte_max_m']:>11.4f}"
                      f"{math.degrees(m['heading_err_max_rad']):>10.2f}"
                      f"{math.degrees(m['steer_max_rad']):>10.2f}{accel:>14}"
                      f"{_time_to_speed_s(log_path, 20.0):>7.2f}{m['solve_ms_p50']:>8.2f}"
                      f"{m['solve_ms_p99']:>8.2f}{m['solver_failures']:>6}", flush=True)
            else:
                print(f"{tracker:<15} worst cte_max_m over {args.seeds} seeds: {worst:.4f}")


if __name__ == "__main__":
    main()
