"""Extremum seeking against fixed gains on the ``acc`` scenario (measures and prints).

    .venv/bin/python bench/acc_esc.py [--tracker lqr] [--duration 240] [--seed 0]
        [--out DIR] [--set key=value ...]

Three runs of the same scenario and seed: the ACC with ESC tuning its gains from the
scenario's initial ones; the ACC with those initial gains fixed (``esc.enabled=false``); and
the ACC with the gains ESC ended with, fixed. For each it prints the objective ESC minimises
(``acc_objective_steady_mean``: the mean over the gap-mode control steps in the steady
regime, ``|gap error| < tracker.acc.esc.max_gap_error_m``; ``acc_objective_gap_mean``: over
every gap-mode step), the smallest gap and safe-gap margin, the jerk, and the gains; and how
far ESC's estimates moved over the last 60 s (the settling figure). The runs go one after
the other (one process), a few minutes each on a loaded two-core machine.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from cosim.log.reader import iter_messages
from cosim.simulation.runner import run
from cosim.simulation.scenario_config import load_config

FIGURES = ("acc_objective_steady_mean", "acc_objective_gap_mean", "gap_min_m",
           "safe_gap_margin_min_m", "ttc_min_s", "jerk_rms_mps3", "acc_gap_mode_t_s",
           "acc_set_speed_t_s", "acc_k_v", "acc_k_x", "acc_k_vrel", "wall_time_s")
GAINS = ("k_v", "k_x", "k_vrel")
SETTLE_WINDOW_S = 60.0


def run_case(name: str, overrides: list[str], args: argparse.Namespace,
             out: Path) -> dict[str, object]:
    config = load_config("acc", overrides=[f"tracker.name={args.tracker}", *args.set,
                                           *overrides],
                         seed=args.seed, duration_s=args.duration)
    result = run(config, out / f"acc-{name}.mcap")
    print(f"\n{name}: {result.log_path} outcome {result.outcome}")
    for key in FIGURES:
        value = result.metrics.get(key)
        print(f"  {key:28s} {value:.4g}" if isinstance(value, float) else
              f"  {key:28s} {value}")
    return dict(result.metrics) | {"log": result.log_path}


def settling(log: Path) -> None:
    rows = [m for _, m in iter_messages(log, "/acc/gains")]
    t = np.array([r["t_s"] for r in rows])
    last = t >= t[-1] - SETTLE_WINDOW_S
    for gain in GAINS:
        values = np.array([r[f"{gain}_estimate"] for r in rows])[last]
        print(f"  {gain}: {values[0]:.4f} -> {values[-1]:.4f} over the last "
              f"{SETTLE_WINDOW_S:.0f} s ({100 * (values[-1] / values[0] - 1):+.1f} %), "
              f"range {100 * np.ptp(values) / values[-1]:.1f} % of the final value")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tracker", default="lqr")
    parser.add_argument("--duration", type=float, default=None)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    args = parser.parse_args()
    out = args.out or Path(tempfile.mkdtemp(prefix="acc-esc-"))
    out.mkdir(parents=True, exist_ok=True)
    tuned = run_case("esc", [], args, out)
    print("\nsettling of ESC's estimates:")
    settling(Path(str(tuned["log"])))
    initial = run_case("fixed-initial", ["tracker.acc.esc.enabled=false"], args, out)
    final = run_case("fixed-tuned", ["tracker.acc.esc.enabled=false",
                                     *(f"tracker.acc.{g}={tuned[f'acc_{g}']}" for g in GAINS)],
                     args, out)
    key = "acc_objective_steady_mean"
    print(f"\n{key}: ESC {tuned[key]:.4g}, fixed initial gains {initial[key]:.4g}, "
          f"fixed tuned gains {final[key]:.4g}")


if __name__ == "__main__":
    main()
