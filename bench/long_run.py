"""Memory over a long run: RSS at 5, 30 and 60 simulated minutes and the log size.

    .venv/bin/python bench/long_run.py [--minutes 60] [--radius 100] [--speed 15]
                                       [--tracker NAME] [--mark MIN] [--tracemalloc]

The car laps a closed circuit (``path.kind: circle``) for ``--minutes`` of simulated time
with full logging. RSS (resident set size, from /proc/self/statm) is printed every
``--mark`` simulated minutes (5), then the growth after the first mark as a ratio and in KB
per simulated second. ``--tracemalloc`` also prints the 12 source lines whose Python
allocations grew most between the first mark and the end (slower: about 2x). The tracker is
``ltv-mpc`` by default (the harness is measured, not the MPC).

What grew before: the run's metrics kept every sample of every error signal as a Python
float in a list (``MetricsAccumulator``); they are now running sums, extremes and last
values (:mod:`cosim.simulation.running_stats`), with only the 20 Hz solve times kept, as
packed doubles (0.6 MB an hour). The MCAP writer keeps one small chunk index per chunk
(the summary section needs them).
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
import tracemalloc
from pathlib import Path

from cosim.simulation.runner import run
from cosim.simulation.scenario_config import load_config


def rss_bytes() -> int:
    """Resident set size of this process (Linux)."""
    with open("/proc/self/statm") as statm:
        return int(statm.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--minutes", type=float, default=60.0)
    parser.add_argument("--radius", type=float, default=100.0, help="circuit radius, m")
    parser.add_argument("--speed", type=float, default=15.0, help="reference speed, m/s")
    parser.add_argument("--tracker", default="ltv-mpc",
                        help="the harness is measured, not the MPC: the quickest by default")
    parser.add_argument("--mark", type=float, default=5.0,
                        help="print RSS every this many simulated minutes")
    parser.add_argument("--tracemalloc", action="store_true")
    parser.add_argument("--out", help="keep the log here (default: a temporary file)")
    args = parser.parse_args()
    duration_s = args.minutes * 60.0
    config = load_config("lane-change", duration_s=duration_s, tracker=args.tracker,
                         overrides=[
        "path.kind=circle", f"path.radius_m={args.radius}", f"path.speed_mps={args.speed}",
        f"initial.speed_mps={args.speed}"])
    n_marks = int(args.minutes / args.mark + 1e-9)
    marks = [args.mark * 60.0 * (i + 1) for i in range(n_marks)]
    rss: dict[float, int] = {}
    snapshots: list[tracemalloc.Snapshot] = []
    wall_start = time.perf_counter()

    def progress(done: float) -> None:
        t_s = done * duration_s
        while marks and t_s >= marks[0]:
            mark = marks.pop(0)
            rss[mark] = rss_bytes()
            print(f"  t = {mark / 60:5.1f} min  RSS {rss[mark] / 2**20:8.1f} MiB  "
                  f"(wall {time.perf_counter() - wall_start:7.1f} s)", flush=True)
            if args.tracemalloc and (len(rss) == 1 or not marks):
                snapshots.append(tracemalloc.take_snapshot())

    if args.tracemalloc:
        tracemalloc.start(8)
    print(f"circuit r = {args.radius} m at {args.speed} m/s for {args.minutes} simulated min",
          flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(args.out) if args.out else Path(tmp) / "long.mcap"
        result = run(config, out, progress)
        size = out.stat().st_size
    print(f"outcome {result.metrics.get('outcome')}  completed {result.completed}  "
          f"cte_max_m {result.metrics['cte_max_m']:.3f}  "
          f"realtime_factor {result.metrics['realtime_factor']:.2f}")
    print(f"log size {size / 2**20:.1f} MiB ({size / duration_s / 1024:.1f} KiB per simulated s)")
    if len(rss) >= 2:
        first, last = min(rss), max(rss)
        growth = rss[last] - rss[first]
        print(f"RSS {rss[first] / 2**20:.1f} MiB at {first / 60:.0f} min -> "
              f"{rss[last] / 2**20:.1f} MiB at {last / 60:.0f} min: "
              f"{100 * growth / rss[first]:+.2f} %, "
              f"{growth / (last - first) / 1024:.2f} KB per simulated s")
    if len(snapshots) == 2:
        print("largest Python allocation growth (tracemalloc):")
        for stat in snapshots[1].compare_to(snapshots[0], "traceback")[:12]:
            frame = stat.traceback[-1]
            print(f"  {stat.size_diff / 1024:+10.1f} KiB  {frame.filename}:{frame.lineno}")


if __name__ == "__main__":
    main()
