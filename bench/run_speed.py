"""Speed of a full run: wall time, realtime factor and MPC solve time (measures and prints).

    .venv/bin/python bench/run_speed.py [--repeats 3] [--scenario lane-change] [--cli]

Prints the median over repeats of each figure measured in this one invocation, so figures
are comparable with each other (same machine, same moment), not across machines; and the
set-up (``setup_time_s``: models built, libraries found, the car settled) of the process's
first run against the median of the runs after it, which reuse what the first built.

``--cli`` times what a user waits for instead: ``cosim run <scenario> --json`` as a whole
process, once per repeat, each a fresh interpreter (imports, set-up, the run, its log written
by the command's parent process, :mod:`cosim.log.piped_recorder`), with the run's own
``realtime_factor`` and tracker step times beside the process's wall time.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from cosim.simulation.runner import run
from cosim.simulation.scenario_config import load_config


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--scenario", default="lane-change")
    parser.add_argument("--set", action="append", default=[], dest="overrides")
    parser.add_argument("--cli", action="store_true",
                        help="time `cosim run` as whole processes (what a user waits for)")
    args = parser.parse_args()
    if args.cli:
        whole_processes(args.scenario, args.overrides, args.repeats)
        return
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for repeat in range(args.repeats):
            config = load_config(args.scenario, overrides=args.overrides)
            result = run(config, Path(tmp) / f"bench-{repeat}.mcap")
            size_kib = (Path(tmp) / f"bench-{repeat}.mcap").stat().st_size / 1024
            rows.append({**result.metrics, "log_kib": size_kib})
    keys = ("wall_time_s", "realtime_factor", "solve_ms_p50", "solve_ms_p99", "solve_ms_max",
            "cte_max_m", "log_kib")
    print(f"{args.scenario}: median of {args.repeats} runs")
    later = [row["setup_time_s"] for row in rows[1:]]
    print(f"  setup_time_s     first run {rows[0]['setup_time_s']:.3f}"
          + (f", later runs {statistics.median(later):.3f}" if later else ""))
    for key in keys:
        values = [row[key] for row in rows]
        print(f"  {key:<16} {statistics.median(values):10.3f}   "
              f"(min {min(values):.3f}, max {max(values):.3f})")


def whole_processes(scenario: str, overrides: list[str], repeats: int) -> None:
    """``cosim run`` ``repeats`` times, each a fresh process: its wall time, and the run's
    realtime factor and tracker step times from its ``--json`` output."""
    cosim = Path(sys.executable).with_name("cosim")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for repeat in range(repeats):
            command = [str(cosim), "run", scenario, "--json", "--out",
                       str(Path(tmp) / f"cli-{repeat}.mcap"),
                       *(f"--set={override}" for override in overrides)]
            start = time.perf_counter()
            done = subprocess.run(command, capture_output=True, text=True, check=False)
            wall_s = time.perf_counter() - start
            if done.returncode != 0:
                raise SystemExit(f"cosim run exited {done.returncode}: {done.stderr.strip()}")
            metrics = json.loads(done.stdout)["metrics"]
            rows.append({"process_wall_s": wall_s, **metrics})
    print(f"cosim run {scenario}: median of {repeats} whole processes")
    for key in ("process_wall_s", "realtime_factor", "wall_time_s", "setup_time_s",
                "step_ms_p50", "step_ms_p99"):
        values = [float(row[key]) for row in rows]
        print(f"  {key:<16} {statistics.median(values):10.3f}   "
              f"(min {min(values):.3f}, max {max(values):.3f})")


if __name__ == "__main__":
    main()
