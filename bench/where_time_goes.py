"""Where a run's time goes, how the tracker step grows with the horizon, and sweep throughput.

    .venv/bin/python bench/where_time_goes.py [--repeats 5] [--parts-duration S] [--set K=V]
        [--horizons 10 20 40 80] [--scaling-duration 8] [--sweep-runs 20]
        [--sweep-duration 15] [--skip-scaling] [--skip-sweep]

Three tables, each measured in this one invocation (figures are comparable with each other,
not across machines or moments; note the load, ``os.getloadavg``, printed at the top):

1. **Parts of the default lane change** (every default: tracker, estimator, full logging),
   per run, median over ``--repeats`` runs in this process: physics with tyres
   (``plant.advance``/``advance_steps`` and ``plant.state``), sensors (``sensor.sample`` and fault
   injection), filter (``estimator.predict``/``update``/``estimate``), tracker step (the
   whole ``tracker.step``), logging (building messages and Foxglove scenes, encoding and
   MCAP writes), metrics (accumulating and the final figures), and the runner's own
   loop (the rest). Each part is timed by wrapping the components the runner builds
   (the wrappers add about a microsecond per call, charged to the part). Process start
   and imports are timed in fresh interpreters: ``python -c pass``, then importing the
   runner (what ``cosim run`` imports before the run), median of the repeats.
2. **Horizon scaling**: ``step_ms_p50``/``step_ms_p99`` (the whole tracker step) and
   ``solve_ms_p50`` of ``dynamic-nmpc`` with each NLP solver (fatrop, ipopt, sqp-rti;
   fatrop and sqp-rti also in CasADi's virtual machine, ``VM``) and of ``ltv-mpc``,
   for N = 10, 20, 40, 80 at ``dt_s`` = 0.05 s, one run of ``--scaling-duration``
   simulated seconds each (the lane change's first swing).
3. **Sweep throughput**: a ``--sweep-runs`` lane-change sweep (plant mass varied) through
   ``cosim sweep``'s process backend with 1 and with 2 workers: runs per second.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from cosim.core.records import Estimate, Plan, VehicleState
from cosim.log import foxglove
from cosim.log.recorder import McapRecorder
from cosim.plant.car import MujocoPlant
from cosim.simulation import run_log, runner
from cosim.simulation.estimator_port import EstimatorPort
from cosim.simulation.metrics import MetricsAccumulator
from cosim.simulation.scenario_config import load_config
from cosim.simulation.sensor_suite import SensorSuite
from cosim.simulation.workshop import Workshop

PARTS = ("physics", "sensors", "filter", "tracker", "logging", "metrics")
"""The parts timed inside the loop; the runner's own bookkeeping is the rest."""

TIMED_METHODS: tuple[tuple[str, type, tuple[str, ...]], ...] = (
    ("physics", MujocoPlant, ("advance", "advance_steps", "state", "apply", "add_yaw_rate")),
    ("sensors", SensorSuite, ("sample",)),
    ("logging", McapRecorder, ("write", "write_finite", "close")),
    ("metrics", MetricsAccumulator, ("add_truth", "add_estimate", "add_update", "add_plan",
                                     "add_command", "result")),
)
"""The classes whose methods are timed, and the part each one's time counts for (the
filter and the tracker are timed on the instances the run builds)."""
FILTER_METHODS = ("predict", "update", "update_many", "estimate", "estimate_at")


class _Stopwatch:
    """Seconds per part, summed over the calls of the wrapped functions."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = defaultdict(float)
        self._active: list[str] = []

    def wrap(self, part: str, function: Callable[..., Any]) -> Callable[..., Any]:
        """``function`` whose time counts for ``part`` (not twice when calls nest)."""

        @functools.wraps(function)
        def timed(*args: Any, **kwargs: Any) -> Any:
            if self._active:  # already inside a timed call: charged to the outer part
                return function(*args, **kwargs)
            self._active.append(part)
            start = time.perf_counter()
            try:
                return function(*args, **kwargs)
            finally:
                self.seconds[part] += time.perf_counter() - start
                self._active.pop()

        return timed

    def wrap_methods(self, part: str, instance: object, names: tuple[str, ...]) -> None:
        for name in names:
            if hasattr(instance, name):  # update_many is optional
                setattr(instance, name, self.wrap(part, getattr(instance, name)))


@contextlib.contextmanager
def _patched(target: object, name: str, value: object) -> Iterator[None]:
    original = getattr(target, name)
    setattr(target, name, value)
    try:
        yield
    finally:
        setattr(target, name, original)


def _timed_run(out: Path, duration_s: float | None,
               overrides: list[str]) -> dict[str, float]:
    """One lane change (the defaults, then ``overrides``) with every part timed; seconds
    per part, loop and total."""
    watch = _Stopwatch()
    config = load_config("lane-change", overrides=overrides, duration_s=duration_s)
    port_init, workshop_tracker = EstimatorPort.__init__, Workshop.tracker

    def timed_port(self: EstimatorPort, estimator: Any) -> None:
        watch.wrap_methods("filter", estimator, FILTER_METHODS)
        port_init(self, estimator)

    def timed_tracker(self: Workshop, *args: Any, **kwargs: Any) -> Any:
        tracker = workshop_tracker(self, *args, **kwargs)
        watch.wrap_methods("tracker", tracker, ("step",))
        return tracker

    class _Foxglove:
        """The log's view of :mod:`cosim.log.foxglove`, each scene builder timed."""

        def __getattr__(self, name: str) -> Any:
            value = getattr(foxglove, name)
            return watch.wrap("logging", value) if callable(value) else value

    patches: list[tuple[object, str, object]] = [
        (cls, name, watch.wrap(part, getattr(cls, name)))
        for part, cls, names in TIMED_METHODS for name in names]
    patches += [
        (EstimatorPort, "__init__", timed_port), (Workshop, "tracker", timed_tracker),
        (run_log, "foxglove", _Foxglove()),
        (VehicleState, "to_message", watch.wrap("logging", VehicleState.to_message)),
        (Estimate, "to_message", watch.wrap("logging", Estimate.to_message)),
        (Plan, "to_message", watch.wrap("logging", Plan.to_message)),
    ]
    with contextlib.ExitStack() as stack:
        for target, name, value in patches:
            stack.enter_context(_patched(target, name, value))
        loop = runner._Run.loop
        loop_seconds: list[float] = []

        def timed_loop(self: Any, *args: Any) -> None:
            start = time.perf_counter()
            try:
                loop(self, *args)
            finally:
                loop_seconds.append(time.perf_counter() - start)

        stack.enter_context(_patched(runner._Run, "loop", timed_loop))
        start_cpu, start = time.process_time(), time.perf_counter()
        result = runner.run(config, out)
        total, total_cpu = time.perf_counter() - start, time.process_time() - start_cpu
    figures = {part: watch.seconds.get(part, 0.0) for part in PARTS}
    figures["runner loop (rest)"] = loop_seconds[0] - sum(figures.values())
    figures["loop"] = loop_seconds[0]
    figures["build, header, finish"] = total - loop_seconds[0]
    figures["run() total"] = total
    figures["run() cpu"] = total_cpu
    figures["realtime_factor"] = float(result.metrics["realtime_factor"])
    figures["step_ms_p50"] = float(result.metrics["step_ms_p50"])
    figures["step_ms_p99"] = float(result.metrics["step_ms_p99"])
    return figures


def _fresh_interpreter_s(code: str) -> float:
    start = time.perf_counter()
    subprocess.run([sys.executable, "-c", code], check=True)
    return time.perf_counter() - start


PART_LABELS = {
    "physics": "physics (MuJoCo, tyres, actuators)",
    "sensors": "sensors",
    "filter": "filter (predict, updates, estimate)",
    "tracker": "tracker step (default tracker)",
    "logging": "logging (messages, scenes, encoding, MCAP)",
    "metrics": "metrics",
    "runner loop (rest)": "the runner's own loop",
}
"""README row labels of the parts (keys of :data:`PARTS` and the loop's rest)."""

README_START = ("<!-- speed-table: generated by bench/where_time_goes.py --readme "
                "docs/guide.md -->")
README_END = "<!-- /speed-table -->"


def parts_table(repeats: int, duration_s: float | None = None,
                overrides: list[str] | None = None) -> dict[str, float]:
    """Print the parts of the default run (median of ``repeats``); return the medians."""
    rows: list[dict[str, float]] = []
    with tempfile.TemporaryDirectory() as tmp:
        for repeat in range(repeats):
            rows.append(_timed_run(Path(tmp) / f"run-{repeat}.mcap", duration_s,
                                   overrides or []))
    start_s = [_fresh_interpreter_s("pass") for _ in range(repeats)]
    imports_s = [_fresh_interpreter_s("import cosim.cli, cosim.simulation.runner")
                 for _ in range(repeats)]
    medians = {key: statistics.median(row[key] for row in rows) for key in rows[0]}
    medians["interpreter start"] = statistics.median(start_s)
    medians["start + imports"] = statistics.median(imports_s)
    loop = medians["loop"]
    simulated = "15 s" if duration_s is None else f"{duration_s:g} s"
    print(f"1. default lane change ({simulated} simulated), per run, median of {repeats}")
    print(f"   {'part':<24}{'seconds':>9}{'share of loop':>15}")
    for key in (*PARTS, "runner loop (rest)", "loop", "build, header, finish", "run() total",
                "run() cpu", "interpreter start", "start + imports"):
        share = f"{100.0 * medians[key] / loop:>14.1f}%" \
            if key in (*PARTS, "runner loop (rest)") else ""
        print(f"   {key:<24}{medians[key]:>9.3f}{share}")
    for key in ("realtime_factor", "step_ms_p50", "step_ms_p99"):
        print(f"   {key:<24}{medians[key]:>9.3f}")
    return medians


def readme_block(medians: dict[str, float], repeats: int, load_start: float,
                 load_end: float) -> str:
    """The README's table of a run's parts, from this invocation's medians."""
    loop = medians["loop"]
    lines = [README_START, "",
             f"Measured {time.strftime('%Y-%m-%d')} on {os.cpu_count()} cores, load average "
             f"{load_start:.2f} at the start and {load_end:.2f} at the end; default lane "
             f"change, every default, full logging, median of {repeats} runs in one process "
             "(the parts are timed by wrapping the components, which adds a little to each):",
             "", "| part | s per run | share of the loop |", "|---|---|---|"]
    for key, label in PART_LABELS.items():
        lines.append(f"| {label} | {medians[key]:.2f} | {100.0 * medians[key] / loop:.0f} % |")
    lines += [f"| the loop | {loop:.2f} | 100 % |",
              f"| start and imports (fresh interpreter) | {medians['start + imports']:.2f} | |",
              "", f"Realtime factor {medians['realtime_factor']:.2f}; tracker step "
              f"`step_ms_p50` {medians['step_ms_p50']:.2f} ms, `step_ms_p99` "
              f"{medians['step_ms_p99']:.2f} ms.", "", README_END]
    return "\n".join(lines)


def write_readme(path: Path, block: str) -> None:
    """Replace the generated block of ``path`` (between its markers) with ``block``."""
    text = path.read_text(encoding="utf-8")
    if README_START not in text or README_END not in text:
        raise SystemExit(f"--readme {path}: expected the markers {README_START!r} and "
                         f"{README_END!r} around the table to replace")
    head, rest = text.split(README_START, 1)
    _, tail = rest.split(README_END, 1)
    path.write_text(head + block + tail, encoding="utf-8")
    print(f"wrote the parts table into {path}")


SCALING_CASES: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("dynamic-nmpc fatrop", ("tracker.name=dynamic-nmpc", "tracker.solver=fatrop")),
    ("dynamic-nmpc fatrop VM", ("tracker.name=dynamic-nmpc", "tracker.solver=fatrop",
                                "tracker.compiled=false")),
    ("dynamic-nmpc ipopt", ("tracker.name=dynamic-nmpc", "tracker.solver=ipopt")),
    ("dynamic-nmpc sqp-rti", ("tracker.name=dynamic-nmpc", "tracker.solver=sqp-rti")),
    ("dynamic-nmpc sqp-rti VM", ("tracker.name=dynamic-nmpc", "tracker.solver=sqp-rti",
                                 "tracker.compiled=false")),
    ("ltv-mpc", ("tracker.name=ltv-mpc",)),
)


def scaling_table(horizons: list[int], duration_s: float) -> None:
    print(f"2. whole tracker step against the horizon (lane change, {duration_s:g} s, dt 0.05 s)")
    print(f"   {'tracker':<22}{'N':>4}{'step p50':>10}{'step p99':>10}{'solve p50':>11}"
          f"{'cte_max':>9}  [ms, ms, ms, m]")
    with tempfile.TemporaryDirectory() as tmp:
        for name, settings in SCALING_CASES:
            for horizon in horizons:
                overrides = [*settings, f"tracker.horizon={horizon}"]
                config = load_config("lane-change", overrides=overrides,
                                     duration_s=duration_s)
                metrics = runner.run(config, Path(tmp) / "scaling.mcap").metrics
                print(f"   {name:<22}{horizon:>4}{metrics['step_ms_p50']:>10.3f}"
                      f"{metrics['step_ms_p99']:>10.3f}{metrics['solve_ms_p50']:>11.3f}"
                      f"{metrics['cte_max_m']:>9.4f}", flush=True)


def sweep_table(runs: int, duration_s: float) -> None:
    # bench/ is the script's own folder, first on sys.path when it runs as a script.
    from sweep_throughput import measure, spec_text

    with tempfile.TemporaryDirectory() as tmp:
        spec = Path(tmp) / "throughput.yaml"
        spec.write_text(spec_text(runs, duration_s))
        serial = measure(spec, Path(tmp) / "one", 1)
        parallel = measure(spec, Path(tmp) / "two", 2)
    print(f"3. sweep of {runs} lane changes x {duration_s:g} s (process backend)")
    print(f"   1 worker   {serial:7.3f} runs/s")
    print(f"   2 workers  {parallel:7.3f} runs/s   ({parallel / serial:.2f}x)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--parts-duration", type=float,
                        help="simulated seconds of the parts' runs (default: the scenario's)")
    parser.add_argument("--horizons", type=int, nargs="+", default=[10, 20, 40, 80])
    parser.add_argument("--scaling-duration", type=float, default=8.0)
    parser.add_argument("--sweep-runs", type=int, default=20)
    parser.add_argument("--sweep-duration", type=float, default=15.0)
    parser.add_argument("--skip-scaling", action="store_true")
    parser.add_argument("--skip-sweep", action="store_true")
    parser.add_argument("--set", action="append", default=[], dest="overrides",
                        help="key=value for the parts' runs, e.g. tracker.compiled=true")
    parser.add_argument("--readme", type=Path,
                        help="write the parts table into this README (between its markers; "
                        "only for the default run: no --set, no --parts-duration)")
    args = parser.parse_args()
    if args.readme is not None and (args.overrides or args.parts_duration is not None):
        parser.error("--readme: expected the default run (no --set, no --parts-duration)")
    load_start = os.getloadavg()[0]
    print(f"load average {load_start:.2f} on {os.cpu_count()} cores")
    medians = parts_table(args.repeats, args.parts_duration, args.overrides)
    if args.readme is not None:
        write_readme(args.readme, readme_block(medians, args.repeats, load_start,
                                               os.getloadavg()[0]))
    if not args.skip_scaling:
        scaling_table(args.horizons, args.scaling_duration)
    if not args.skip_sweep:
        sweep_table(args.sweep_runs, args.sweep_duration)
    print(f"load average {os.getloadavg()[0]:.2f} at the end")


if __name__ == "__main__":
    main()
