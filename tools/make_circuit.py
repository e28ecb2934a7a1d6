"""Write the built-in circuit ``cosim/scenarios/tracks/ring.csv`` (racetrack-database layout).

A smooth closed curve made for cosim, not a real track: the polar curve
``r(theta) = R (1 + 0.25 cos 2 theta + 0.12 sin 3 theta)`` with R = 120 m (about 780 m a lap,
tightest radius about 45 m), resampled every 2 m of arc length, with half-widths of 5 m that
narrow to 4 m on one side along part of the lap. Run ``python tools/make_circuit.py`` to
regenerate it; the file is deterministic.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

RADIUS_M = 120.0
STEP_M = 2.0
OUT = Path(__file__).resolve().parent.parent / "cosim" / "scenarios" / "tracks" / "ring.csv"


def main() -> None:
    theta = np.linspace(0.0, 2.0 * np.pi, 20000, endpoint=False)
    r = RADIUS_M * (1.0 + 0.25 * np.cos(2.0 * theta) + 0.12 * np.sin(3.0 * theta))
    x, y = r * np.cos(theta), r * np.sin(theta)
    step = np.hypot(np.diff(x, append=x[0]), np.diff(y, append=y[0]))
    s = np.concatenate(([0.0], np.cumsum(step)[:-1]))
    length = s[-1] + step[-1]
    target = np.arange(0.0, length - STEP_M / 2, STEP_M)
    xs, ys = np.interp(target, s, x), np.interp(target, s, y)
    phase = 2.0 * np.pi * target / length
    right = 5.0 - 1.0 * np.clip(np.sin(phase), 0.0, None)
    left = np.full_like(right, 5.0)
    lines = ["# x_m,y_m,w_tr_right_m,w_tr_left_m"]
    lines += [f"{a:.4f},{b:.4f},{c:.3f},{d:.3f}" for a, b, c, d in zip(xs, ys, right, left,
                                                                       strict=True)]
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text("\n".join(lines) + "\n")
    print(f"{OUT}: {len(xs)} points, {length:.1f} m")


if __name__ == "__main__":
    main()
