"""A sweep's worker processes: forked from a server that has imported the run's modules, with
the sweep's environment as it is when the pool starts
(:func:`cosim.sweeps.execute.pool_context`)."""

from __future__ import annotations

import concurrent.futures
import multiprocessing
import os
import sys

import pytest

from cosim.sweeps.execute import PRELOADED_MODULES, _init_worker, pool_context

SETTING = "COSIM_TEST_POOL_SETTING"


def _pool(context: multiprocessing.context.BaseContext) -> concurrent.futures.Executor:
    """A one-worker pool started as a sweep starts its pools."""
    return concurrent.futures.ProcessPoolExecutor(
        1, mp_context=context, initializer=_init_worker,
        initargs=(os.getpid(), dict(os.environ)))


def imported_before_any_task() -> list[str]:
    """In a worker: the preloaded modules it has without importing them itself."""
    return [name for name in PRELOADED_MODULES if name in sys.modules]


@pytest.mark.skipif("forkserver" not in multiprocessing.get_all_start_methods(),
                    reason="a platform without a forkserver spawns its workers")
def test_workers_are_forked_with_the_runs_modules_imported() -> None:
    context = pool_context()
    assert context.get_start_method() == "forkserver"
    with _pool(context) as pool:
        imported = pool.submit(imported_before_any_task).result()
    assert "cosim.simulation.runner" in imported  # MuJoCo, CasADi and the loop, once
    assert imported == list(PRELOADED_MODULES)


def test_a_worker_takes_the_sweeps_environment_as_it_is_now(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The first pool starts the forkserver (if this process has none yet) without the
    setting; a pool started after the sweep's process has set it still gets it, though its
    worker is forked from a server that never had it."""
    monkeypatch.delenv(SETTING, raising=False)
    context = pool_context()
    with _pool(context) as pool:
        assert pool.submit(os.getenv, SETTING).result() is None
    monkeypatch.setenv(SETTING, "set later")
    with _pool(context) as pool:
        assert pool.submit(os.getenv, SETTING).result() == "set later"
