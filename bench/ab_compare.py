"""Two source trees of cosim, run interleaved: speed ratio and whether the answers changed.

    .venv/bin/python bench/ab_compare.py BEFORE_TREE AFTER_TREE [--seeds 0 1 2 3 4]
        [--scenario lane-change] [--set key=value ...] [--set-after key=value ...]

Each run is a fresh interpreter with ``PYTHONPATH`` set to one tree (that tree's
``cosim``, ``tracker`` and ``estimation`` are imported, the rest from this environment),
alternating before/after for every seed, so both see the same machine load. A tree is a
checkout, e.g. ``git worktree add /tmp/before <commit>``, or the same tree twice with
``--set-after`` overrides for the second (e.g. ``tracker.compiled=true``). Prints per
seed the run's CPU time (``time.process_time`` around ``run()``, less sensitive to other
jobs than wall time), ``realtime_factor``, ``step_ms_p50`` and the answers (``cte_max_m``,
``cte_rms_m``, ``est_pos_rmse_m``, ``est_yaw_rmse_rad``) of both trees; then the medians
and the ratio of CPU times.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

CHILD = """
import json, sys, time
from pathlib import Path
from cosim.simulation.runner import run
from cosim.simulation.scenario_config import load_config
scenario, seed, out, overrides = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4:]
config = load_config(scenario, overrides=[f"seed={seed}", *overrides])
start = time.process_time()
result = run(config, Path(out))
cpu_s = time.process_time() - start
print(json.dumps({"cpu_s": cpu_s, **{k: v for k, v in result.metrics.items()
                  if isinstance(v, (int, float))}}))
"""

ANSWERS = ("cte_max_m", "cte_rms_m", "est_pos_rmse_m", "est_yaw_rmse_rad")


def _run(tree: Path, scenario: str, seed: int, overrides: list[str], out: Path) -> dict:
    env = dict(os.environ, PYTHONPATH=str(tree), MUJOCO_GL="disable")
    completed = subprocess.run(
        [sys.executable, "-c", CHILD, scenario, str(seed), str(out), *overrides],
        env=env, cwd=tree, capture_output=True, text=True, check=True)
    # cwd: ``python -c`` puts the working directory first on sys.path, ahead of PYTHONPATH.
    return json.loads(completed.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("before", type=Path)
    parser.add_argument("after", type=Path)
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4])
    parser.add_argument("--scenario", default="lane-change")
    parser.add_argument("--set", action="append", default=[], dest="overrides")
    parser.add_argument("--set-after", action="append", default=[], dest="after_overrides")
    args = parser.parse_args()
    overrides = {"before": args.overrides, "after": [*args.overrides, *args.after_overrides]}
    print(f"load average {os.getloadavg()[0]:.2f}")
    rows: dict[str, list[dict]] = {"before": [], "after": []}
    with tempfile.TemporaryDirectory() as tmp:
        for seed in args.seeds:
            for label, tree in (("before", args.before), ("after", args.after)):
                result = _run(tree, args.scenario, seed, overrides[label],
                              Path(tmp) / f"{label}-{seed}.mcap")
                rows[label].append(result)
                answers = "  ".join(f"{k} {result.get(k, float('nan')):.6g}" for k in ANSWERS)
                print(f"seed {seed} {label:6s} cpu {result['cpu_s']:6.2f} s  realtime "
                      f"{result['realtime_factor']:5.2f}  step_ms_p50 "
                      f"{result.get('step_ms_p50', float('nan')):6.2f}  {answers}", flush=True)
    for key in ("cpu_s", "realtime_factor", "step_ms_p50", "solve_ms_p50"):
        before = statistics.median(r.get(key, float("nan")) for r in rows["before"])
        after = statistics.median(r.get(key, float("nan")) for r in rows["after"])
        print(f"median {key:16s} before {before:8.3f}  after {after:8.3f}  "
              f"after/before {after / before:6.3f}")
    for key in ANSWERS:
        worst = max(abs(a.get(key, 0.0) / b[key] - 1.0) if b.get(key) else 0.0
                    for a, b in zip(rows["after"], rows["before"], strict=True))
        print(f"largest relative change of {key}: {worst:.2%}")
    print(f"load average {os.getloadavg()[0]:.2f} at the end")


if __name__ == "__main__":
    main()
