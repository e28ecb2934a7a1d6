"""The Python API: load a configuration, run it, sweep it, and get the results back.

What ``cosim run`` and ``cosim sweep`` do, callable from a notebook, a tuning script or an
optimiser, with the same validation and the same errors (every user error is a
:class:`cosim.core.exceptions.CosimError` whose message is the line the command line prints)::

    import cosim

    config = cosim.load_config("lane-change", seed=1, overrides=["tracker.horizon=30"])
    result = cosim.run(config, out="logs/lane-change-h30.mcap")
    print(result.completed, result.outcome, result.metrics["cte_max_m"])

Many runs in one process (a tuning loop) share their built parts through a
:class:`Workshop`: the MuJoCo model, the filter's models and the NLP are built by the first
run and restarted for the next ones of the same car, filter and tracker (set-up about
0.02 s instead of 0.25 s; the same numbers as runs built afresh)::

    workshop = cosim.Workshop()
    for seed in range(20):
        cosim.run(cosim.load_config("lane-change", seed=seed), out=f"logs/s{seed}.mcap",
                  workshop=workshop)

``import cosim`` alone imports none of this (the package resolves ``cosim.run`` and the other
names on first use), so importing the package stays light and has no side effects. The
run's own machinery is :mod:`cosim.simulation.runner`; the sweep's is
:mod:`cosim.sweeps.driver`. A worked example: ``docs/api.md``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from cosim.core.exceptions import ConfigError
from cosim.log.output_claim import claim_output
from cosim.simulation.runner import RunResult
from cosim.simulation.runner import run as _run_loop
from cosim.simulation.scenario_config import ScenarioConfig
from cosim.simulation.scenario_config import load_config as _load_config
from cosim.simulation.workshop import Workshop

if TYPE_CHECKING:
    from cosim.sweeps.driver import SweepOutcome

__all__ = ["RunResult", "ScenarioConfig", "SweepOutcome", "Workshop", "load_config", "run",
           "sweep"]


def load_config(
    scenario: str | Path,
    *,
    config_file: str | Path | Sequence[str | Path] | None = None,
    overrides: Sequence[str] = (),
    seed: int | None = None,
    duration_s: float | None = None,
    tracker: str | None = None,
    estimator: str | None = None,
) -> ScenarioConfig:
    """The validated configuration of a run, resolved as ``cosim run`` resolves it.

    ``scenario`` is a built-in name (``cosim scenarios``) or a YAML file; ``config_file`` a
    YAML merged over it, or a list of them merged in order (a later file wins a key both
    set); then ``seed``, ``duration_s`` (``sim.duration_s``), ``tracker``
    (``tracker.name``), ``estimator`` (``estimator.name``) and the ``overrides``, each
    ``"key.path=value"`` as ``--set`` takes it (the value is read as YAML). Raises
    :class:`cosim.core.exceptions.ConfigError` naming the bad key or value and what was expected.
    """
    if duration_s is not None and not (math.isfinite(duration_s) and duration_s > 0):
        raise ConfigError(f"duration_s = {duration_s}: expected a number of seconds > 0")
    if isinstance(overrides, str):  # one string would be read character by character
        raise ConfigError(f"overrides = {overrides!r}: expected a list of 'key.path=value'")
    files = None if config_file is None else \
        [str(config_file)] if isinstance(config_file, (str, Path)) else \
        [str(path) for path in config_file]
    return _load_config(str(scenario), files, list(overrides), seed, duration_s, tracker,
                        estimator)


def run(
    config: ScenarioConfig | str,
    out: str | Path,
    *,
    force: bool = False,
    progress: Callable[[float], None] | None = None,
    workshop: Workshop | None = None,
) -> RunResult:
    """Run one configuration and log it to the MCAP file ``out``; its :class:`RunResult`.

    ``config`` is a :class:`ScenarioConfig` (from :func:`load_config`) or a scenario name or
    path, loaded with its defaults. ``out`` is refused, as ``--out`` is, when it is a folder
    or already exists (unless ``force``), or while another run writes it. ``progress`` is
    called with the fraction done. ``workshop`` keeps the parts this run builds for the
    next run given the same workshop (module docstring); without one, every part is built
    afresh.

    A run that ends badly is a result, not an exception: ``result.completed`` is false when
    it aborted (``result.reason`` says why), and ``result.outcome`` names how it ended
    (``ok``, ``off_road``, ``spun`` ...; see :mod:`cosim.simulation.outcome`). An interrupt
    (Ctrl-C, SIGTERM) ends the run with ``reason == "interrupted"`` and the log kept.
    """
    if isinstance(config, str):
        config = load_config(config)
    if not isinstance(config, ScenarioConfig):
        raise ConfigError(f"config = {type(config).__name__}: expected a ScenarioConfig "
                          "(cosim.load_config) or a scenario name")
    if workshop is not None and not isinstance(workshop, Workshop):
        raise ConfigError(f"workshop = {type(workshop).__name__}: expected a cosim.Workshop")
    with claim_output(Path(out), "out", force) as path:
        return _run_loop(config, path, progress, workshop=workshop)


def sweep(
    spec: str | Path,
    out: str | Path,
    *,
    workers: int | None = None,
    backend: str = "process",
    keep_logs: bool = False,
    resume: bool = False,
    yes: bool = False,
    force: bool = False,
) -> SweepOutcome:
    """Run the sweep spec ``spec`` (YAML, see :mod:`cosim.sweeps.spec`) into directory ``out``.

    As ``cosim sweep SPEC --out DIR``: ``results.jsonl``, ``results.csv``, ``results.json``,
    ``summary.md`` and the plots land in ``out`` (their paths: ``outcome.files``);
    ``workers`` parallel runs (default: the usable cores), ``backend`` ``process`` or
    ``ray``, ``keep_logs`` keeps each run's MCAP under ``out/logs``, ``resume`` finishes
    an interrupted sweep in ``out``, ``force`` starts afresh in an ``out`` that has files
    (refused otherwise), ``yes`` allows more than 10 000 runs. A bad spec raises
    :class:`cosim.core.exceptions.CosimError` before any run; an interrupt re-raises
    ``KeyboardInterrupt`` with the finished rows kept.

    The ``process`` backend starts its workers from a fresh process (multiprocessing's
    ``forkserver``, or ``spawn`` where there is none): they import the caller's main module,
    so a script that calls this keeps its work under
    ``if __name__ == "__main__":``, as every script with a process pool must.
    """
    spec_path = Path(spec)
    if not spec_path.is_file():
        raise ConfigError(f"{str(spec)!r}: no such file (expected a sweep spec YAML)")
    if backend not in ("process", "ray"):
        raise ConfigError(f"backend = {backend!r}: expected process or ray")
    if workers is not None and workers < 1:
        raise ConfigError(f"workers = {workers}: expected at least 1")
    from cosim.sweeps.driver import check_sweep_dir, run_sweep

    out_dir = Path(out)
    check_sweep_dir(out_dir, force, resume)
    return run_sweep(spec_path, out_dir, workers, backend, keep_logs, resume, yes=yes,
                     force=force)


def __getattr__(name: str) -> Any:
    """``SweepOutcome``, imported with the sweep machinery when asked: a script that only
    loads and runs configurations does not import it (multiprocessing, the sweep's
    results and plots: some 25 ms of its first call)."""
    if name == "SweepOutcome":
        from cosim.sweeps.driver import SweepOutcome

        return SweepOutcome
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
