"""The ACC's steady objective over a grid of fixed gap gains (measures and prints).

    .venv/bin/python bench/acc_objective_map.py [--kx 0.02,0.04,...] [--kvrel 0.3,0.5,...]
        [--duration 160] [--from-s 40] [--seed 0] [--tracker lqr] [--set key=value ...]

Where is the optimum extremum seeking should find on the ``acc`` scenario? Each grid point
is one run of ``acc`` with ESC off and the gains ``(K_x, K_vrel)`` fixed, started in the
steady regime it tunes in (the ego at the lead's mean speed, at the desired gap behind it,
so that no approach from 400 m dilutes the figure). From ``--from-s`` to the end it prints,
over the control steps, the mean objective ``E[J]``, what ESC actually descends with
``log_objective`` (``E[log(J + floor)]``) and the three parts of J (gap error^2, relative
speed^2, jerk^2). The runs go one after the other (one process), about a minute each on a
loaded two-core machine.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from cosim.log.reader import iter_messages
from cosim.simulation.runner import run
from cosim.simulation.scenario_config import load_config

CENTRE_TO_BUMPERS_M = 4.55
"""``traffic.lead.gap_m`` (ego's centre of gravity to the lead's centre) minus the gap the
range sensor measures (front bumper to rear bumper): the ego's front overhang plus half the
lead's length, from the models (``acc-braking``: 46 m is a 41.45 m gap)."""


def floats(text: str) -> list[float]:
    return [float(part) for part in text.split(",") if part]


def steady_start(seed: int, tracker: str, extra: list[str]) -> list[str]:
    """Overrides that start ``acc`` at the desired gap behind the lead, at its mean speed."""
    base = load_config("acc", overrides=[f"tracker.name={tracker}", *extra], seed=seed)
    lead = base.traffic["lead"]
    acc = base.tracker.acc
    speed = float(lead["speed_mps"])
    desired_gap_m = acc.standstill_gap_m + acc.time_gap_s * speed
    return [f"initial.speed_mps={speed}",
            f"traffic.lead.gap_m={desired_gap_m + CENTRE_TO_BUMPERS_M}"]


def measure(log: Path, from_s: float, floor: float) -> dict[str, float]:
    modes = [m for _, m in iter_messages(log, "/acc/mode")]
    objective = np.array([m["objective"] for _, m in iter_messages(log, "/acc/objective")])

    def column(key: str) -> np.ndarray:
        return np.array([np.nan if m[key] is None else m[key] for m in modes])

    t_s = column("t_s")
    accel = column("accel_mps2")
    jerk = np.diff(accel, prepend=accel[0]) / np.diff(t_s, prepend=t_s[0] - 1.0)
    gap_error = column("gap_m") - column("desired_gap_m")
    window = t_s >= from_s
    return {"J": float(np.mean(objective[window])),
            "logJ": float(np.mean(np.log(objective[window] + floor))),
            "gap2": float(np.nanmean(gap_error[window] ** 2)),
            "vrel2": float(np.nanmean(column("range_rate_mps")[window] ** 2)),
            "jerk2": float(np.mean(jerk[window] ** 2)),
            "gap_mode": float(np.mean([m["gap_mode"] for m, w in zip(modes, window,
                                                                      strict=True) if w]))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kx", type=floats, default=floats("0.02,0.04,0.07,0.1,0.15"))
    parser.add_argument("--kvrel", type=floats, default=floats("0.3,0.45,0.6,0.8"))
    parser.add_argument("--duration", type=float, default=160.0)
    parser.add_argument("--from-s", type=float, default=40.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--tracker", default="lqr")
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    args = parser.parse_args()
    out = args.out or Path(tempfile.mkdtemp(prefix="acc-map-"))
    out.mkdir(parents=True, exist_ok=True)
    start = steady_start(args.seed, args.tracker, args.set)
    print(f"steady start: {' '.join(start)}; window {args.from_s:g}-{args.duration:g} s, "
          f"seed {args.seed}")
    print(f"{'k_x':>6} {'k_vrel':>6} {'E[J]':>7} {'E[logJ]':>8} {'gap^2':>7} {'vrel^2':>7} "
          f"{'jerk^2':>7} {'gap mode':>8}", flush=True)
    for k_x in args.kx:
        for k_vrel in args.kvrel:
            config = load_config("acc", overrides=[
                f"tracker.name={args.tracker}", *args.set, *start,
                "tracker.acc.esc.enabled=false", f"tracker.acc.k_x={k_x}",
                f"tracker.acc.k_vrel={k_vrel}"], seed=args.seed, duration_s=args.duration)
            result = run(config, out / f"map-{k_x:g}-{k_vrel:g}.mcap")
            if result.outcome != "ok":
                print(f"{k_x:6.3g} {k_vrel:6.3g} outcome {result.outcome}", flush=True)
                continue
            m = measure(result.log_path, args.from_s, config.tracker.acc.esc.objective_floor)
            print(f"{k_x:6.3g} {k_vrel:6.3g} {m['J']:7.3f} {m['logJ']:8.3f} {m['gap2']:7.3f} "
                  f"{m['vrel2']:7.3f} {m['jerk2']:7.3f} {m['gap_mode']:8.2f}", flush=True)


if __name__ == "__main__":
    main()
