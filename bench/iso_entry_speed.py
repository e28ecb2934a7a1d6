"""The highest ISO 3888-1 entry speed each tracker drives without hitting a gate (prints).

    .venv/bin/python bench/iso_entry_speed.py [--trackers dynamic-mpc ltv-mpc]
        [--speeds-kmh 60 64 68 72 76 80] [--seeds 0] [--workers 2]

Runs the ``iso-lane-change`` scenario (cone lanes sized from the sedan's 1.8 m body) with
the car entering at and holding each speed (``path.speed_mps`` and ``initial.speed_mps``
together) on the sweep's process pool, and prints, per tracker, the gates hit at every
speed and seed and the highest speed at which every seed hit none (and every slower speed
passed too).
"""

from __future__ import annotations

import argparse

from cosim.sweeps.execute import ProcessBackend
from cosim.sweeps.spec import RunTask


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trackers", nargs="+", default=["dynamic-mpc", "ltv-mpc"])
    parser.add_argument("--speeds-kmh", nargs="+", type=float,
                        default=[60.0, 64.0, 68.0, 72.0, 76.0, 80.0])
    parser.add_argument("--seeds", nargs="+", type=int, default=[0])
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    tasks = []
    for tracker in args.trackers:
        for kmh in args.speeds_kmh:
            mps = round(kmh / 3.6, 4)
            for seed in args.seeds:
                tasks.append(RunTask(
                    run_id=len(tasks), point=0, seed=seed,
                    params=(("tracker", tracker), ("entry_kmh", kmh)),
                    scenario="iso-lane-change",
                    overrides=(f"path.speed_mps={mps}", f"initial.speed_mps={mps}"),
                    tracker=tracker, estimator=None, duration_s=None, log_path=None))
    rows: list[dict] = []

    def land(row: dict) -> None:
        rows.append(row)
        params = dict(row["params"])
        metrics = row["metrics"]
        print(f"{params['tracker']:>14} {params['entry_kmh']:5.1f} km/h seed {row['seed']}: "
              f"gates_hit {metrics.get('gates_hit')} cte_max {metrics.get('cte_max_m'):.3f} m "
              f"{row['error']}", flush=True)

    ProcessBackend(args.workers).run(tasks, land)
    for tracker in args.trackers:
        best = None
        for kmh in sorted(args.speeds_kmh):
            group = [r for r in rows if dict(r["params"]) == {"tracker": tracker,
                                                              "entry_kmh": kmh}]
            if all(not r["error"] and r["metrics"].get("gates_hit") == 0 for r in group):
                best = kmh
            else:
                break
        print(f"{tracker}: highest entry speed with no gate hit: "
              f"{'none' if best is None else f'{best:g} km/h'}")


if __name__ == "__main__":
    main()
