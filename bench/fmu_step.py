"""The cost of an FMU tracker's call, C against Python, FMI 2 against 3 (measures, prints).

    .venv/bin/python bench/fmu_step.py [--calls 5000] [--runs]

Builds the example FMUs (examples/fmu/build.py: a Stanley law in C, a pure pursuit in
Python with pythonfmu/pythonfmu3) and times, for each, the median and 90th percentile of

- ``fmu call``: set the FMU's inputs + ``doStep`` + get its two outputs
  (:meth:`tracker.fmu.slave.FmuSlave.step`), the overhead an FMU adds to a control step;
- ``tracker step``: the whole :meth:`tracker.fmu.tracker.FmuTracker.step` as the runner
  calls it (the estimate projected on the lane-change path, the preview points, the call).

The C FMU reads 6 inputs, the Python FMU 52 (2 + 25 preview points). With ``--runs`` it also
runs the lane change with each FMU on seeds 1, 2 and 3 (the examples' settings were chosen
on seed 0) and prints the outcome, the max CTE and the median step time. Figures from one
invocation are comparable with each other; quote ratios.
"""

from __future__ import annotations

import argparse
import importlib.util
import statistics
import tempfile
import time
from pathlib import Path
from types import ModuleType

import numpy as np

from cosim.core.records import Estimate
from cosim.simulation.runner import run, scenario_course
from cosim.simulation.scenario_config import load_config
from tracker.fmu.tracker import FmuTracker

BUILD_SCRIPT = Path(__file__).resolve().parents[1] / "examples" / "fmu" / "build.py"
HELD_OUT_SEEDS = (1, 2, 3)


def _builder() -> ModuleType:
    spec = importlib.util.spec_from_file_location("example_fmu_build", BUILD_SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _times_us(function, calls: int) -> tuple[float, float]:  # noqa: ANN001 - a callable
    """Median and 90th percentile of ``calls`` calls of ``function(k)`` [us]."""
    samples = []
    for k in range(calls):
        start = time.perf_counter()
        function(k)
        samples.append((time.perf_counter() - start) * 1e6)
    return statistics.median(samples), float(np.percentile(samples, 90))


def _time_fmu(fmu: Path, calls: int) -> dict[str, tuple[float, float]]:
    config = load_config("lane-change", tracker=f"fmu:{fmu}")
    period = config.sim.control_period_s
    reference = scenario_course(config).reference
    names = ("x_m", "y_m", "yaw_rad", "vx_mps", "vy_mps", "yaw_rate_radps")
    tracker = FmuTracker(config.tracker, period)
    try:
        inputs = [0.01 * i for i in range(len(tracker.description.inputs))]
        calls_us = _times_us(lambda k: tracker.slave.step(k * period, period, inputs), calls)
        tracker.reset()

        def step(k: int) -> None:
            state = np.array([20.0 * k * period, 0.1, 0.01, 20.0, 0.0, 0.0])
            tracker.step(k * period, Estimate(k * period, names, state, np.eye(6)), reference)

        steps_us = _times_us(step, calls)
    finally:
        tracker.close()
    return {"fmu call": calls_us, "tracker step": steps_us}


def _held_out_runs(fmu: Path, out_dir: Path) -> str:
    rows = []
    for seed in HELD_OUT_SEEDS:
        config = load_config("lane-change", tracker=f"fmu:{fmu}", seed=seed)
        metrics = run(config, out_dir / f"{fmu.stem}-{seed}.mcap").metrics
        rows.append(f"seed {seed}: {metrics['outcome']}, cte_max {metrics['cte_max_m']:.3f} m, "
                    f"step p50 {metrics['step_ms_p50']:.3f} ms")
    return "; ".join(rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--calls", type=int, default=5000)
    parser.add_argument("--runs", action="store_true",
                        help="also run the lane change on the held-out seeds 1-3")
    args = parser.parse_args()
    builder = _builder()
    with tempfile.TemporaryDirectory(prefix="cosim-bench-fmu-") as work:
        out = Path(work)
        fmus = [builder.build_c_fmu(out, 2), builder.build_c_fmu(out, 3),
                builder.build_python_fmu(out, 2), builder.build_python_fmu(out, 3)]
        print(f"median / p90 of {args.calls} calls [us]")
        for fmu in fmus:
            figures = _time_fmu(fmu, args.calls)
            print(f"  {fmu.stem:<20} " + "  ".join(
                f"{name} {median:7.1f} / {p90:7.1f}" for name, (median, p90) in figures.items()))
        if args.runs:
            print("lane change, held-out seeds (the examples were set up on seed 0):")
            for fmu in fmus:
                print(f"  {fmu.stem:<20} {_held_out_runs(fmu, out)}")


if __name__ == "__main__":
    main()
