"""Solve time of every MPC tracker with every solver option it has (measures and prints).

    .venv/bin/python bench/solve_time.py [--seeds 0 1 2] [--repeats 3] [--tracker NAME ...]

Runs the lane change (MuJoCo sedan, EKF in the loop) in-process for each tracker of
:data:`tracker.registry.TRACKER_NAMES` except ``open-loop``, once per solver option that
applies to it:

* the NMPCs (``kinematic-nmpc``, ``dynamic-nmpc``): every ``tracker.solver``, and for
  ``sqp-rti`` every ``tracker.rti_qp_solver`` (:mod:`tracker.mpc.nmpc`);
* ``ltv-mpc`` and ``dynamic-mpc``: every ``qp_solver`` of their section, if the tracker
  exists in this checkout;

plus ``kinematic-nmpc`` at N = 20, dt = 0.05 s with each solver (the issue's speed case;
the default tuning is N = 25). A case that fails to build or run is reported with the
reason and skipped. Prints one row per case and seed: the per-step solve time's median
and 99th percentile, the maximum cross-track error and the number of failed solves; with
``--repeats`` the median of each figure over the repeats. Figures are comparable within
one invocation (same machine, same moment), not across machines: the timings of a shared
machine move by tens of percent from minute to minute.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import statistics
import tempfile
from pathlib import Path

from cosim.simulation.runner import run
from cosim.simulation.scenario_config import load_config
from tracker.config import TrackerConfig
from tracker.registry import TRACKER_NAMES

NMPC_NAMES: tuple[str, ...] = ("kinematic-nmpc", "dynamic-nmpc")
"""Trackers built on :class:`tracker.mpc.nmpc.Nmpc`, which take ``tracker.solver``."""

QP_TRACKERS: tuple[tuple[str, str, str], ...] = (
    ("ltv-mpc", "tracker.mpc.ltv_mpc_config", "tracker.ltv_mpc.qp_solver"),
    ("dynamic-mpc", "tracker.mpc.dynamic_mpc_config", "tracker.dynamic_mpc.qp_solver"),
)
"""QP-based trackers: name, the module holding its ``QP_SOLVERS``, the setting's key."""

SPEED_CASE: tuple[str, ...] = ("tracker.horizon=20", "tracker.dt_s=0.05")
"""The issue's speed case for ``kinematic-nmpc``: N = 20, dt = 0.05 s."""

FIGURES: tuple[str, ...] = ("solve_ms_p50", "solve_ms_p99", "cte_max_m", "solver_failures")


@dataclasses.dataclass(frozen=True)
class Case:
    """One tracker with one solver option: a row of the table."""

    tracker: str
    option: str
    overrides: tuple[str, ...]


def _choices(name: str) -> tuple[str, ...]:
    """The choices of the ``TrackerConfig`` setting ``name``."""
    field = {f.name: f for f in dataclasses.fields(TrackerConfig)}[name]
    return tuple(field.metadata["choices"])


def nmpc_options() -> list[tuple[str, tuple[str, ...]]]:
    """Every NMPC solver option as (label, overrides)."""
    options = []
    for solver in _choices("solver"):
        if solver == "sqp-rti":
            options += [(f"sqp-rti/{qp}", (f"tracker.solver={solver}",
                                           f"tracker.rti_qp_solver={qp}"))
                        for qp in _choices("rti_qp_solver")]
        else:
            options.append((solver, (f"tracker.solver={solver}",)))
    return options


def cases(selected: tuple[str, ...]) -> list[Case]:
    """Every (tracker, option) to run, in table order."""
    out: list[Case] = []
    qp_trackers = {name: (module, key) for name, module, key in QP_TRACKERS}
    for name in TRACKER_NAMES:
        if name == "open-loop" or (selected and name not in selected):
            continue
        if name in NMPC_NAMES:
            out += [Case(name, label, overrides) for label, overrides in nmpc_options()]
        elif name in qp_trackers:
            module, key = qp_trackers[name]
            try:
                solvers = importlib.import_module(module).QP_SOLVERS
            except (ImportError, AttributeError) as error:
                print(f"{name}: no QP_SOLVERS ({error}); default solver only")
                solvers = ()
            out += [Case(name, qp, (f"{key}={qp}",)) for qp in solvers] or [
                Case(name, "default", ())]
        else:
            out.append(Case(name, "default", ()))
    if "kinematic-nmpc" in TRACKER_NAMES and (not selected or "kinematic-nmpc" in selected):
        out += [Case("kinematic-nmpc", f"{label} N=20", overrides + SPEED_CASE)
                for label, overrides in nmpc_options()]
    return out


def measure(case: Case, seed: int, repeats: int, tmp: Path) -> dict[str, float] | str:
    """The median of each figure over ``repeats`` runs, or why the case failed."""
    rows = []
    for repeat in range(repeats):
        try:
            config = load_config("lane-change", overrides=list(case.overrides), seed=seed,
                                 tracker=case.tracker)
            result = run(config, tmp / f"solve-time-{repeat}.mcap")
        except Exception as error:  # noqa: BLE001 - a bench reports, it does not stop
            return f"{type(error).__name__}: {error}".splitlines()[0]
        rows.append(result.metrics)
    return {key: statistics.median(float(row[key]) for row in rows) for key in FIGURES}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0])
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--tracker", nargs="+", default=[], dest="trackers",
                        help="only these tracker names (default: all but open-loop)")
    args = parser.parse_args()
    header = (f"{'tracker':<16} {'option':<20} {'seed':>4} {'p50 [ms]':>9} {'p99 [ms]':>9} "
              f"{'cte_max [m]':>11} {'failures':>8}")
    print(f"lane-change, median of {args.repeats} run(s) per row")
    print(header)
    print("-" * len(header))
    with tempfile.TemporaryDirectory() as tmp:
        for case in cases(tuple(args.trackers)):
            for seed in args.seeds:
                figures = measure(case, seed, args.repeats, Path(tmp))
                if isinstance(figures, str):
                    print(f"{case.tracker:<16} {case.option:<20} {seed:>4} skipped: {figures}")
                    continue
                print(f"{case.tracker:<16} {case.option:<20} {seed:>4} "
                      f"{figures['solve_ms_p50']:>9.3f} {figures['solve_ms_p99']:>9.3f} "
                      f"{figures['cte_max_m']:>11.4f} {figures['solver_failures']:>8.0f}",
                      flush=True)


if __name__ == "__main__":
    main()
