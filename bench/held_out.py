"""The default stack on held-out cases: generated circuits x sampled sedans x run seeds.

    .venv/bin/python bench/held_out.py                         # the judging set, 200 runs
    .venv/bin/python bench/held_out.py --tracker ltv-mpc       # the same, another tracker
    .venv/bin/python bench/held_out.py --cases tuning          # the tuning set, 50 runs
    .venv/bin/python bench/held_out.py --circuits 4 --cars 2   # a corner of a set, quickly

Two sets that share no seed:

* ``judging`` (``examples/held-out.yaml``): circuits ``path.seed`` 1000-1039 x sedans
  ``vehicle_sample`` 1000-1004 x run seed 1000, 200 runs; never used to tune anything;
* ``tuning``: circuits 0-9 x sedans 0-4 x run seed 0, 50 runs: what the defaults
  (the profile's shares of grip and tracker bounds, the smoothing) were chosen on.

Each run is 20 s of the ``generated-circuit`` scenario (:mod:`tracker.paths.generated_circuit`,
:mod:`cosim.plant.sedan_sampler`) through ``cosim sweep``'s process pool. A case passes when
the run completes with outcome ``ok`` (no spin, rollover, off-road or collision), the car
stays within the track (``track_limit_exceedances`` 0) and its peak lateral acceleration
stays within the profile's limit + 10 % (``lat_accel_max_mps2`` against
``profile_lat_accel_max_mps2``). The bench prints the counts, the pass fraction and the
worst cases, each with the ``cosim run`` command that reproduces it.
"""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from cosim.api import sweep

ROOT = Path(__file__).resolve().parents[1]
JUDGING_SPEC = ROOT / "examples" / "held-out.yaml"
TUNING = {"path.seed": list(range(10)), "vehicle_sample": list(range(5)), "seeds": [0]}
"""The tuning set: circuits, sedans and run seeds (none shared with the judging set)."""
LAT_ACCEL_MARGIN = 1.10
"""The peak lateral acceleration allowed, over the profile's limit."""
WORST_SHOWN = 10


@dataclass(frozen=True)
class Case:
    """One judged run."""

    circuit: int
    car: int
    seed: int
    outcome: str
    exceedances: int
    lat_ratio: float
    """Peak lateral acceleration over the profile's limit."""
    cte_max_m: float
    speed_err_max_mps: float
    """The largest |speed - profile| (how far the car lags the profile into a bend)."""
    error: str

    @property
    def failures(self) -> list[str]:
        found = []
        if self.error or self.outcome != "ok":
            found.append(self.outcome or "error")
        if self.exceedances:
            found.append(f"track limits x{self.exceedances}")
        if not self.lat_ratio <= LAT_ACCEL_MARGIN:
            found.append(f"lat accel {self.lat_ratio:.2f} x limit")
        return found

    def command(self, tracker: str | None, duration_s: float) -> str:
        chosen = f" --tracker {tracker}" if tracker else ""
        return (f"cosim run generated-circuit --set path.seed={self.circuit} --set "
                f"vehicle_sample={self.car} --seed {self.seed} --duration {duration_s:g}"
                f"{chosen}")


def _spec(cases: str, tracker: str | None, circuits: int | None, cars: int | None
          ) -> dict[str, Any]:
    spec = yaml.safe_load(JUDGING_SPEC.read_text())
    if cases == "tuning":
        spec["name"], spec["seeds"] = "held-out-tuning", TUNING["seeds"]
        spec["grid"] = {"path.seed": TUNING["path.seed"],
                        "vehicle_sample": TUNING["vehicle_sample"]}
    if circuits is not None:
        spec["grid"]["path.seed"] = spec["grid"]["path.seed"][:circuits]
    if cars is not None:
        spec["grid"]["vehicle_sample"] = spec["grid"]["vehicle_sample"][:cars]
    if tracker:
        spec["tracker"] = tracker
    return spec


def _case(row: dict[str, Any]) -> Case:
    metrics = row.get("metrics") or {}
    limit = metrics.get("profile_lat_accel_max_mps2") or math.nan
    peak = metrics.get("lat_accel_max_mps2")
    return Case(
        circuit=int(row["params"]["path.seed"]), car=int(row["params"]["vehicle_sample"]),
        seed=int(row["seed"]), outcome=str(metrics.get("outcome", "")),
        exceedances=int(metrics.get("track_limit_exceedances") or 0),
        lat_ratio=(peak / limit) if peak is not None else math.nan,
        cte_max_m=float(metrics.get("cte_max_m") or math.nan),
        speed_err_max_mps=float(metrics.get("speed_err_max_mps") or math.nan),
        error=str(row.get("error", "")))


def _severity(case: Case) -> tuple[float, ...]:
    return (float(bool(case.error or case.outcome != "ok")), float(case.exceedances > 0),
            case.lat_ratio if math.isfinite(case.lat_ratio) else math.inf, case.cte_max_m)


def report(cases: list[Case], tracker: str | None, duration_s: float) -> None:
    """Counts, pass fraction and the worst cases with their commands."""
    n = len(cases)
    bad_outcomes = [c for c in cases if c.error or c.outcome != "ok"]
    exceeded = [c for c in cases if c.exceedances]
    over = [c for c in cases if not c.lat_ratio <= LAT_ACCEL_MARGIN]
    passed = [c for c in cases if not c.failures]
    print(f"cases {n}, tracker {tracker or 'the scenario default (dynamic-nmpc)'}, "
          f"{duration_s:g} s each")
    outcomes: dict[str, int] = {}
    for case in cases:
        outcomes[case.outcome or "error"] = outcomes.get(case.outcome or "error", 0) + 1
    print("outcomes: " + ", ".join(f"{k} {v}" for k, v in sorted(outcomes.items())))
    print(f"not ok (spin, rollover, off-road, collision, error): {len(bad_outcomes)}")
    print(f"track-limit exceedance: {len(exceeded)} ({100.0 * len(exceeded) / max(n, 1):.1f} %)")
    ratios = [c.lat_ratio for c in cases if math.isfinite(c.lat_ratio)]
    print(f"lateral acceleration above the profile's limit + 10 %: {len(over)}; peak over "
          f"limit: max {max(ratios, default=math.nan):.3f}, median "
          f"{sorted(ratios)[len(ratios) // 2] if ratios else math.nan:.3f}")
    for name in ("cte_max_m", "speed_err_max_mps"):
        values = sorted(getattr(c, name) for c in cases if math.isfinite(getattr(c, name)))
        if values:
            print(f"{name}: median {values[len(values) // 2]:.3f}, max {values[-1]:.3f}")
    print(f"pass fraction: {len(passed)}/{n} = {len(passed) / max(n, 1):.3f}")
    done = (not bad_outcomes and not over and len(exceeded) <= 0.02 * n)
    print(f"target (no failure, <= 2 % track-limit exceedances, no lateral excess): "
          f"{'met' if done else 'not met'}")
    print(f"\nworst {min(WORST_SHOWN, n)}:")
    for case in sorted(cases, key=_severity, reverse=True)[:WORST_SHOWN]:
        why = ", ".join(case.failures) or "passes"
        print(f"  circuit {case.circuit:>5} car {case.car:>5} seed {case.seed:>5}: "
              f"cte_max {case.cte_max_m:.3f} m, lat accel {case.lat_ratio:.3f} x limit; "
              f"{why}\n    {case.command(tracker, duration_s)}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cases", choices=("judging", "tuning"), default="judging")
    parser.add_argument("--tracker", default=None, help="default: the scenario's")
    parser.add_argument("--circuits", type=int, default=None, help="only the first N")
    parser.add_argument("--cars", type=int, default=None, help="only the first N")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path, default=None,
                        help="sweep folder (default /tmp/held-out-<cases>-<tracker>)")
    parser.add_argument("--resume", action="store_true", help="finish an interrupted run")
    parser.add_argument("--report-only", action="store_true",
                        help="judge the rows already in --out, run nothing")
    args = parser.parse_args()
    spec = _spec(args.cases, args.tracker, args.circuits, args.cars)
    out = args.out or Path(f"/tmp/held-out-{args.cases}-{args.tracker or 'default'}")
    spec_path = out.with_name(out.name + "-spec.yaml")
    if not args.report_only:
        spec_path.parent.mkdir(parents=True, exist_ok=True)
        spec["scenario"] = "generated-circuit"
        spec_path.write_text(yaml.safe_dump(spec, sort_keys=False))
        sweep(spec_path, out, workers=args.workers, resume=args.resume)
    rows = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()
            if line.strip()]
    print(f"set: {args.cases} (circuits {spec['grid']['path.seed'][0]}-"
          f"{spec['grid']['path.seed'][-1]}, sedans {spec['grid']['vehicle_sample'][0]}-"
          f"{spec['grid']['vehicle_sample'][-1]}, run seeds {spec['seeds']}); rows in {out}")
    report([_case(row) for row in rows], args.tracker, float(spec["duration_s"]))


if __name__ == "__main__":
    main()
