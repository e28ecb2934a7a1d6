"""Shared fixtures: closed-loop runs are expensive, so each is made once per session; and
the order in which pytest-xdist's workers take the modules."""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest

from cosim.simulation.runner import RunResult, run, run_unlogged
from cosim.simulation.scenario_config import load_config


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Under pytest-xdist (``make test``), each worker's share starts with modules that hold
    slow tests (:func:`balanced_order`); a run in one process keeps the collection order."""
    workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "0"))
    if workers >= 2:
        items[:] = balanced_order(items, workers)


def balanced_order(items: list[pytest.Item], workers: int) -> list[pytest.Item]:
    """The tests in an order that lets ``workers`` workers finish together.

    pytest-xdist's ``worksteal`` scheduler hands worker ``j`` the ``j``-th of ``workers``
    contiguous shares of the list, and an idle worker then takes the second half of
    another's tests not yet started. In collection order a 20-s test could start last, its
    worker running it while the other had nothing left (measured: 16 s of the suite's 283
    with one core idle). Here the modules with ``slow`` tests (whole modules, in their
    order: a module's fixtures are built once per worker that runs it) are dealt to the
    shares, the most slow tests first, each to the share with the fewest so far; each share
    starts with its slow modules and is filled to its size with the other modules' tests.
    The slow tests start early on every worker, and what is left to steal at the end is
    short."""
    modules: dict[str, list[pytest.Item]] = {}
    for item in items:
        modules.setdefault(item.nodeid.partition("::")[0], []).append(item)

    slow = {name: sum(item.get_closest_marker("slow") is not None for item in module)
            for name, module in modules.items()}
    heavy = sorted((name for name in modules if slow[name]), key=slow.__getitem__,
                   reverse=True)
    light = [item for name, module in modules.items() if not slow[name] for item in module]
    shares: list[list[pytest.Item]] = [[] for _ in range(workers)]
    weights = [0] * workers
    for name in heavy:
        j = weights.index(min(weights))
        shares[j].extend(modules[name])
        weights[j] += slow[name]
    ordered: list[pytest.Item] = []
    remaining, start = len(items), 0
    for j, share in enumerate(shares):  # the scheduler's shares: what is left, divided
        size = remaining // (workers - j)
        remaining -= size
        fill = max(0, size - len(share))
        ordered += share + light[start:start + fill]
        start += fill
    return ordered + light[start:]


def run_scenario(tmp_dir: Path, name: str, *overrides: str, seed: int = 0,
                 duration_s: float | None = None, estimator: str | None = None,
                 logged: bool = True) -> RunResult:
    """The scenario with its log in ``tmp_dir``; ``logged=False``: no log (the same metrics,
    bit for bit, without building and writing some 17,000 messages a lane change), for a
    test that reads the metrics alone."""
    config = load_config(name, overrides=list(overrides), seed=seed, duration_s=duration_s,
                         estimator=estimator)
    if not logged:
        return run_unlogged(config)
    return run(config, tmp_dir / f"{name}-{seed}.mcap")


@pytest.fixture(scope="session", autouse=True)
def compiled_libraries(worker_id: str) -> None:
    """The default run's compiled libraries (NLP, filter, tyres, physics step) built before
    any test, so that on a machine with an empty cache (CI) no test's output depends on
    whether it happened to be the first to build one (a build prints a one-line note).

    Every pytest-xdist worker builds them, each library under its build lock: the second
    worker takes them in the opposite order, so that the two compile different libraries
    at the same time (the NLP on one core, the physics step, tyres and filter on the
    other) instead of one waiting for the other's every build."""
    from cosim.plant.car import MujocoPlant
    from estimation.registry import make_estimator
    from tracker.registry import make_tracker

    config = load_config("lane-change")
    builds = [
        lambda: MujocoPlant(config.plant, config.sim.physics_dt_s, config.initial),
        lambda: make_estimator(config.estimator, config.initial, config.tracker.model),
        lambda: make_tracker(config.tracker, config.manoeuvre, config.sim.control_period_s),
    ]
    number = worker_id.removeprefix("gw")  # "gw0", "gw1", ...; "master" without xdist
    if number.isdigit() and int(number) % 2:
        builds.reverse()
    for build in builds:
        build()


@pytest.fixture(scope="session")
def short_run(tmp_path_factory: pytest.TempPathFactory) -> RunResult:
    """Two seconds of the lane change, seed 0."""
    return run_scenario(tmp_path_factory.mktemp("short"), "lane-change", duration_s=2.0)


@pytest.fixture(scope="session")
def lane_change_run(tmp_path_factory: pytest.TempPathFactory) -> RunResult:
    """The full 15 s lane change with the EKF in the loop (the README's demo)."""
    return run_scenario(tmp_path_factory.mktemp("full"), "lane-change")


@dataclass(frozen=True)
class Called:
    """What a ``cosim`` command line gave: its exit code and what it printed."""

    returncode: int
    stdout: str
    stderr: str


@pytest.fixture
def cosim_in_process(capsys: pytest.CaptureFixture[str],
                     monkeypatch: pytest.MonkeyPatch) -> Callable[..., Called]:
    """Runs ``cosim ARGS`` through :func:`cosim.cli.main` in this process (from ``cwd`` if
    given): the same parser, messages and exit codes as the console script, without an
    interpreter start per call. ``tests/cli/test_cli.py`` runs the console script itself."""
    from cosim.cli import main

    def call(*args: str, cwd: Path | None = None) -> Called:
        if cwd is not None:
            monkeypatch.chdir(cwd)
        capsys.readouterr()
        try:
            code = main(list(args))
        except SystemExit as stop:  # argparse's own refusals
            code = stop.code if isinstance(stop.code, int) else 2
        printed = capsys.readouterr()
        return Called(code, printed.out, printed.err)

    return call
