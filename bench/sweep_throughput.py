"""Sweep throughput: the same small sweep with 1 and with N workers (measures and prints).

    .venv/bin/python bench/sweep_throughput.py [--workers 2] [--runs 8] [--duration 5]

Runs a grid of ``--runs`` lane changes of ``--duration`` simulated seconds each (plant mass
varied, one seed) through ``cosim sweep``'s process backend, once with one worker and once
with ``--workers``, and prints runs per second of each and their ratio. Each sweep includes
starting its worker processes, as a user's sweep does: forked from the process's forkserver,
which the first sweep starts (it imports MuJoCo, CasADi and the runner once, about half a
second; :func:`cosim.sweeps.execute.pool_context`). On an idle machine with 2 cores the
target ratio is >= 1.7; figures
taken while other jobs load the machine say nothing about the sweep.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import yaml

from cosim.sweeps.driver import run_sweep


def spec_text(runs: int, duration_s: float) -> str:
    masses = [round(1200.0 + 800.0 * i / max(1, runs - 1), 1) for i in range(runs)]
    return yaml.safe_dump({
        "name": "throughput", "scenario": "lane-change", "duration_s": duration_s,
        "seeds": [0], "grid": {"plant.mass_kg": masses},
    })


def measure(spec: Path, out: Path, workers: int) -> float:
    """Runs per second of one sweep of ``spec`` on ``workers`` processes."""
    start = time.perf_counter()
    outcome = run_sweep(spec, out, workers=workers)
    elapsed = time.perf_counter() - start
    if outcome.errors:
        raise SystemExit(f"{outcome.errors} runs ended in an error; see {out}/summary.md")
    return outcome.runs / elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--runs", type=int, default=8)
    parser.add_argument("--duration", type=float, default=5.0, help="simulated s per run")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        spec = Path(tmp) / "throughput.yaml"
        spec.write_text(spec_text(args.runs, args.duration))
        serial = measure(spec, Path(tmp) / "one", 1)
        parallel = measure(spec, Path(tmp) / "many", args.workers)
    print(f"sweep of {args.runs} lane changes x {args.duration:g} s")
    print(f"  1 worker    {serial:7.3f} runs/s")
    print(f"  {args.workers} workers   {parallel:7.3f} runs/s")
    print(f"  ratio       {parallel / serial:7.2f}x  (target >= 1.7x on 2 idle cores)")


if __name__ == "__main__":
    main()
