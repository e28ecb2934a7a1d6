"""How a circuit's set-up time grows with its point count: read, check and lay out the course.

Writes circuits of N points (a closed curve of ``--lap-m`` metres with a varying curvature,
racetrack-database layout) to a temporary folder and times
:func:`cosim.simulation.runner.scenario_course` of the ``track`` scenario on each: the CSV
read and checks (:mod:`tracker.paths.track_csv`), the spline, the friction-limited speed
profile and the track bounds. Prints the median of ``--repeats`` timings per N and the
ratio to the previous N (10x the points: about 10x the time for linear set-up, 100x for
quadratic).

    python bench/track_setup.py                       # 2 000, 20 000, 200 000 points
    python bench/track_setup.py --points 20000 --repeats 5
"""

from __future__ import annotations

import argparse
import math
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from cosim.simulation.runner import scenario_course
from cosim.simulation.scenario_config import load_config


def write_circuit(path: Path, points: int, lap_m: float) -> None:
    """A closed curve r(phi) = R (1 + 0.2 cos 3 phi), scaled to ``lap_m``, ``points`` points."""
    phi = np.linspace(0.0, 2.0 * math.pi, points, endpoint=False)
    radius = 1.0 + 0.2 * np.cos(3.0 * phi)
    x, y = radius * np.cos(phi), radius * np.sin(phi)
    scale = lap_m / float(np.sum(np.hypot(np.diff(x, append=x[0]), np.diff(y, append=y[0]))))
    rows = "\n".join(f"{a:.4f},{b:.4f},5.0,5.0" for a, b in zip(scale * x, scale * y,
                                                                  strict=True))
    path.write_text("# x_m,y_m,w_tr_right_m,w_tr_left_m\n" + rows + "\n")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--points", type=int, nargs="+", default=[2_000, 20_000, 200_000])
    parser.add_argument("--lap-m", type=float, default=20_000.0,
                        help="lap length [m] (default 20 km, the Nordschleife's order)")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    previous = None
    print(f"{'points':>8}  {'spacing m':>9}  {'set-up s (median)':>17}  {'x previous':>10}")
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.points:
            path = Path(tmp) / f"circuit-{n}.csv"
            write_circuit(path, n, args.lap_m)
            config = load_config("track", overrides=[f"path.file={path}"])
            times = []
            for _ in range(args.repeats):
                start = time.perf_counter()
                scenario_course(config)
                times.append(time.perf_counter() - start)
            median = statistics.median(times)
            ratio = f"{median / previous:.1f}" if previous else ""
            print(f"{n:>8}  {args.lap_m / n:>9.3g}  {median:>17.3f}  {ratio:>10}", flush=True)
            previous = median


if __name__ == "__main__":
    main()
