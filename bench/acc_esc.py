"""Extremum seeking against fixed gains on the ``acc`` scenario (measures and prints).

    .venv/bin/python bench/acc_esc.py [--tracker lqr] [--duration S] [--seeds 0,1,2,3,4]
        [--esc-only] [--out DIR] [--set key=value ...]

For each seed, three runs of the same scenario: the ACC with ESC tuning its gains from the
scenario's initial ones; the ACC with those initial gains fixed (``esc.enabled=false``); and
the ACC with the gains ESC ended with, fixed (``--esc-only``: the first run only). For each
it prints the objective ESC minimises, as the mean over the steady gap-keeping steps
(``acc_objective_steady_mean``: ``|gap error| < tracker.acc.esc.max_gap_error_m``) and over
the run's last ``tracker.acc.esc.settle_window_s`` (``acc_objective_final_mean``), the
smallest gap and safe-gap margin, the jerk and the gains; for the ESC run, how far each gain
estimate moved over that last window (``acc_<gain>_drift_pct``, ``esc_gain_drift_pct``,
``esc_gains_settled``: the settling judgement, :mod:`cosim.simulation.traffic_loop`). A
table per seed closes. The runs go one after the other (one process), a few minutes each on
a loaded two-core machine.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from cosim.simulation.runner import run
from cosim.simulation.scenario_config import load_config

FIGURES = ("acc_objective_steady_mean", "acc_objective_final_mean", "gap_min_m",
           "safe_gap_margin_min_m", "ttc_min_s", "jerk_rms_mps3", "acc_gap_mode_t_s",
           "acc_set_speed_t_s", "acc_k_v", "acc_k_x", "acc_k_vrel", "wall_time_s")
SETTLING = ("acc_k_v_drift_pct", "acc_k_x_drift_pct", "acc_k_vrel_drift_pct",
            "esc_gain_drift_pct", "esc_gains_settled")
GAINS = ("k_v", "k_x", "k_vrel")


def seeds(text: str) -> list[int]:
    return [int(part) for part in text.split(",") if part]


def run_case(name: str, seed: int, overrides: list[str], args: argparse.Namespace,
             out: Path) -> dict[str, object]:
    config = load_config("acc", overrides=[f"tracker.name={args.tracker}", *args.set,
                                           *overrides],
                         seed=seed, duration_s=args.duration)
    result = run(config, out / f"acc-{name}-{seed}.mcap")
    print(f"\nseed {seed}, {name}: {result.log_path} outcome {result.outcome}")
    keys = FIGURES + (SETTLING if config.tracker.acc.esc.enabled else ())
    for key in keys:
        value = result.metrics.get(key)
        print(f"  {key:28s} {value:.4g}" if isinstance(value, float) else
              f"  {key:28s} {value}", flush=True)
    return dict(result.metrics)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tracker", default="lqr")
    parser.add_argument("--duration", type=float, default=None)
    parser.add_argument("--seeds", type=seeds, default=[0])
    parser.add_argument("--esc-only", action="store_true")
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    args = parser.parse_args()
    out = args.out or Path(tempfile.mkdtemp(prefix="acc-esc-"))
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for seed in args.seeds:
        tuned = run_case("esc", seed, [], args, out)
        row = {"seed": seed, "tuned": tuned}
        if not args.esc_only:
            row["initial"] = run_case("fixed-initial", seed, ["tracker.acc.esc.enabled=false"],
                                      args, out)
            row["final"] = run_case(
                "fixed-tuned", seed, ["tracker.acc.esc.enabled=false",
                                      *(f"tracker.acc.{g}={tuned[f'acc_{g}']}" for g in GAINS)],
                args, out)
        rows.append(row)
    print("\nseed  K_x     K_vrel  drift %  settled  |  J steady: initial  ESC  tuned-fixed"
          "  |  J last window: initial  ESC  tuned-fixed")
    for row in rows:
        tuned = row["tuned"]
        line = (f"{row['seed']:4d}  {tuned['acc_k_x']:.4f}  {tuned['acc_k_vrel']:.4f}  "
                f"{tuned['esc_gain_drift_pct']:7.2f}  {tuned['esc_gains_settled']!s:7s}")
        if "initial" in row:
            line += "  |  " + "  ".join(
                f"{row[case][key]:.3f}" for key in ("acc_objective_steady_mean",
                                                    "acc_objective_final_mean")
                for case in ("initial", "tuned", "final"))
        print(line)


if __name__ == "__main__":
    main()
