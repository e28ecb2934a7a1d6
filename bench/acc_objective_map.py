"""The ACC's steady objective around fixed gap gains: its map over a grid, and what ESC's
demodulation sees of it (measures and prints).

    .venv/bin/python bench/acc_objective_map.py [--kx 0.02,0.04,...] [--kvrel 0.3,0.5,...]
        [--duration 160] [--from-s 40] [--seed 0] [--tracker lqr] [--set key=value ...]
    .venv/bin/python bench/acc_objective_map.py --phase [--kx 0.02] [--kvrel 0.3]
        [--wx 0.13] [--wvrel 0.17] [--duration 1000] [--from-s 60] ...

Where is the optimum extremum seeking should find on the ``acc`` scenario? Each grid point
is one run of ``acc`` with ESC off and the gains ``(K_x, K_vrel)`` fixed, started in the
steady regime it tunes in (the ego at the lead's mean speed, at the desired gap behind it,
so that no approach from 400 m dilutes the figure). From ``--from-s`` to the end it prints,
over the control steps, the mean objective ``E[J]``, what ESC actually descends with
``log_objective`` (``E[log(J + floor)]``) and the three parts of J (gap error^2, relative
speed^2, jerk^2). The runs go one after the other (one process), about a minute each on a
loaded two-core machine.

``--phase``: one run from the same steady start, the gains held at the first ``--kx`` and
``--kvrel`` but perturbed as extremum seeking perturbs them (its step set to 1e-9, so the
estimates stay put), at ``--wx`` and ``--wvrel`` rad/s. Over the control steps from
``--from-s`` on, with ``n = J / mean(J) - 1`` (the normalised objective), it prints for each
gain ``2 mean(n sin(omega t)) / a`` (in phase: what ESC integrates, an estimate of the
relative gradient ``dJ/dtheta / J``) and ``2 mean(n cos(omega t)) / a`` (in quadrature), the
phase of the response they imply, and a standard error from 10 blocks. Through a plant mode
slower than the perturbation the response lags; past 90 degrees the in-phase part, and with
it the direction ESC moves in, changes sign. Compare with the static gradient from the grid
(fixed gains on either side).
"""

from __future__ import annotations

import argparse
import math
import tempfile
from pathlib import Path

import numpy as np

from cosim.log import topics
from cosim.log.reader import iter_messages
from cosim.simulation.runner import run
from cosim.simulation.scenario_config import load_config

CENTRE_TO_BUMPERS_M = 4.55
"""``traffic.lead.gap_m`` (ego's centre of gravity to the lead's centre) minus the gap the
range sensor measures (front bumper to rear bumper): the ego's front overhang plus half the
lead's length, from the models (``acc-braking``: 46 m is a 41.45 m gap)."""


PHASE_BLOCKS = 10
FROZEN_STEP = 1e-9
"""ESC's step in ``--phase``: positive (the tuning rule) and too small to move a gain."""


def floats(text: str) -> list[float]:
    return [float(part) for part in text.split(",") if part]


def steady_start(seed: int, tracker: str, extra: list[str], duration_s: float) -> list[str]:
    """Overrides that start ``acc`` at the desired gap behind the lead, at its mean speed, on
    a path long enough for ``duration_s`` (and the lead's speed swing)."""
    base = load_config("acc", overrides=[f"tracker.name={tracker}", *extra], seed=seed)
    lead = base.traffic["lead"]
    acc = base.tracker.acc
    speed = float(lead["speed_mps"])
    gap_m = acc.standstill_gap_m + acc.time_gap_s * speed + CENTRE_TO_BUMPERS_M
    reach_m = gap_m + (speed + float(lead["amplitude_mps"])) * duration_s
    return [f"initial.speed_mps={speed}", f"traffic.lead.gap_m={gap_m}",
            f"path.length_m={max(base.path.length_m, reach_m + 100.0)}"]


def measure(log: Path, from_s: float, floor: float) -> dict[str, float]:
    modes = [m for _, m in iter_messages(log, topics.ACC_MODE)]
    objective = np.array([m["objective"] for _, m in iter_messages(log, topics.ACC_OBJECTIVE)])

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


def phase(args: argparse.Namespace, start: list[str], out: Path) -> None:
    """``--phase`` (module docstring)."""
    k_x, k_vrel = args.kx[0], args.kvrel[0]
    config = load_config("acc", overrides=[
        f"tracker.name={args.tracker}", *args.set, *start,
        f"tracker.acc.k_x={k_x}", f"tracker.acc.k_vrel={k_vrel}",
        f"tracker.acc.esc.k_x.frequency_radps={args.wx}",
        f"tracker.acc.esc.k_vrel.frequency_radps={args.wvrel}",
        *(f"tracker.acc.esc.{gain}.step={FROZEN_STEP}" for gain in ("k_v", "k_x", "k_vrel"))],
        seed=args.seed, duration_s=args.duration)
    result = run(config, out / f"phase-{k_x:g}-{k_vrel:g}-{args.wx:g}-{args.wvrel:g}.mcap")
    rows = [m for _, m in iter_messages(result.log_path, topics.ACC_OBJECTIVE)]
    t_s = np.array([r["t_s"] for r in rows])
    objective = np.array([r["objective"] for r in rows])
    window = t_s >= args.from_s
    t_s, objective = t_s[window], objective[window]
    normalised = objective / objective.mean() - 1.0
    esc = config.tracker.acc.esc
    print(f"outcome {result.outcome}; K_x {k_x:g}, K_vrel {k_vrel:g}; "
          f"{t_s[0]:.0f}-{t_s[-1]:.0f} s, mean J {objective.mean():.3f}")
    for name, omega, amplitude in (("k_x", args.wx, esc.k_x.amplitude),
                                   ("k_vrel", args.wvrel, esc.k_vrel.amplitude)):
        in_phase = 2.0 * normalised * np.sin(omega * t_s) / amplitude
        quadrature = 2.0 * normalised * np.cos(omega * t_s) / amplitude
        blocks = [float(np.mean(b)) for b in np.array_split(in_phase, PHASE_BLOCKS)]
        angle_deg = math.degrees(math.atan2(-float(np.mean(quadrature)),
                                            float(np.mean(in_phase))))
        print(f"  {name:6s} omega {omega:g} rad/s: in phase {np.mean(in_phase):+.3f} "
              f"(standard error {np.std(blocks) / math.sqrt(PHASE_BLOCKS):.3f}), quadrature "
              f"{np.mean(quadrature):+.3f}, phase of the response {angle_deg:+.0f} deg")


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
    parser.add_argument("--phase", action="store_true")
    parser.add_argument("--wx", type=float, default=0.13)
    parser.add_argument("--wvrel", type=float, default=0.17)
    args = parser.parse_args()
    out = args.out or Path(tempfile.mkdtemp(prefix="acc-map-"))
    out.mkdir(parents=True, exist_ok=True)
    start = steady_start(args.seed, args.tracker, args.set, args.duration)
    if args.phase:
        phase(args, start, out)
        return
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
