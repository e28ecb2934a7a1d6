"""Running a sweep's tasks: one run as a function of plain data, and backends that run many.

:func:`execute_task` is the unit of work: it builds the run's configuration with
:func:`cosim.simulation.scenario_config.load_config` from the task's overrides and seed,
calls :func:`cosim.simulation.runner.run` and returns the row as a plain dictionary (no numpy,
no paths), so it crosses process and machine boundaries unchanged. It never raises for a failed
run: an exception (``SystemExit`` from a user's plug-in included) or a diverging plant becomes
a row with ``error`` set, and the sweep goes on. Only
an interrupted run (SIGINT/SIGTERM inside the worker) is not a result: its row has
``interrupted: true`` and the driver drops it, so ``--resume`` runs it again.

Two backends run a list of tasks and hand each row to a callback as it finishes, in
completion order (the driver sorts by run id, so the order never shows in the results):

* :class:`ProcessBackend`: ``concurrent.futures.ProcessPoolExecutor`` on
  :func:`pool_context`. MuJoCo and CasADi hold threads and native state that a ``fork`` of
  the sweep's process would copy half-way, so no worker is forked from it: where the
  platform has it, multiprocessing's ``forkserver`` starts one fresh server process, which
  imports the run's modules once (:data:`PRELOADED_MODULES`: imports only, no run, no
  thread, no library loaded) and forks every worker of the sweep from that state; elsewhere
  each worker is a ``spawn``, importing everything afresh (about 0.45 s of CPU a worker,
  and again for every pool a sweep starts). A worker is handed a batch of
  consecutive tasks (:func:`execute_batch`, sized by :func:`batch_size`), which share one
  :class:`~cosim.simulation.workshop.Workshop`: the runs of one grid point differ in their
  seed only, so they reuse the car, the filter and the tracker the first one built.
* :class:`RayBackend`: the same function as a Ray task, on a local Ray or the cluster at
  ``ray_address`` (or the ``RAY_ADDRESS`` environment variable). Ray is an optional extra
  (``pip install .[ray]``), imported only here, only when asked for.

A run's result depends on its task only (seed and overrides from the spec, never from the
worker), so every backend and worker count gives the same rows.
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import ctypes
import datetime
import math
import multiprocessing
import os
import queue as queue_module
import select
import signal
import sys
import threading
import time
import warnings
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from multiprocessing.managers import SyncManager
from pathlib import Path
from typing import TYPE_CHECKING, Any

from cosim.core.exceptions import CosimError
from cosim.core.interrupts import drop_unraisable_interrupts
from cosim.sweeps.spec import RunTask

if TYPE_CHECKING:
    from cosim.simulation.workshop import Workshop

THREAD_LIMITS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
"""Environment variables that keep a worker's numeric libraries to one thread each: the
pool already uses every core, and oversubscribed cores make every run slower."""


def default_workers() -> int:
    """The cores this process may use (affinity-aware where the platform tells)."""
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return max(1, os.cpu_count() or 1)


def _plain(value: Any) -> Any:
    """A metric value as JSON-ready Python: non-finite floats become ``None``."""
    if isinstance(value, bool) or value is None or isinstance(value, (int, str)):
        return value
    try:
        number = float(value)
    except (TypeError, ValueError):
        return str(value)
    return number if math.isfinite(number) else None


def _now() -> str:
    return datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="milliseconds")


def _run_task(task: RunTask, row: dict[str, Any], workshop: Workshop | None) -> None:
    """Run ``task`` and fill ``row``'s metrics and error (:func:`execute_task`)."""
    from cosim.core.config_fields import to_dict
    from cosim.simulation.belief_check import BeliefMismatchWarning
    from cosim.simulation.beliefs import mismatch_table
    from cosim.simulation.filter_health import FilterInconsistentWarning
    from cosim.simulation.outcome import SEVERITY
    from cosim.simulation.runner import run, run_unlogged
    from cosim.simulation.scenario_config import load_config

    config = load_config(task.scenario, None, list(task.overrides), task.seed,
                         task.duration_s, task.tracker, task.estimator)
    row["mismatch"] = [r.text() for r in mismatch_table(to_dict(config))]
    with warnings.catch_warnings():
        # The end-of-run checks are in the row's metrics (belief_mismatches,
        # filter_warnings): a warning from every run of a sweep would drown its progress.
        warnings.simplefilter("ignore", BeliefMismatchWarning)
        warnings.simplefilter("ignore", FilterInconsistentWarning)
        if task.log_path is None:  # no log kept: none written (the same metrics)
            result = run_unlogged(config, workshop=workshop)
        else:
            Path(task.log_path).parent.mkdir(parents=True, exist_ok=True)
            result = run(config, Path(task.log_path), workshop=workshop)
    row["metrics"] = {k: _plain(v) for k, v in result.metrics.items()}
    if result.abort_reason == "interrupted":
        row["interrupted"] = True
    if not result.completed and result.outcome not in SEVERITY:
        # An event (a collision, a spin) ends a run as a result, judged by the pass
        # criteria; an abort (an exception, diverging physics, an interrupt) is an error.
        row["error"] = result.abort_reason or "run did not complete"


def execute_task(task: RunTask, workshop: Workshop | None = None) -> dict[str, Any]:
    """Run one task and return its row: ids, varied values, seed, metrics, error, times.

    The row's ``metrics`` holds every metric the run produced (non-finite values as
    ``None``); ``error`` is ``""`` for a run that completed, else the exception or the abort
    reason. ``started_at``/``finished_at`` are UTC wall-clock stamps. ``workshop`` keeps the
    parts earlier tasks built (:mod:`cosim.simulation.workshop`; the same row, bit for bit).
    """
    row: dict[str, Any] = {
        "run_id": task.run_id, "point": task.point, "seed": task.seed,
        "params": dict(task.params), "metrics": {}, "error": "", "interrupted": False,
        "log": task.log_path or "", "started_at": _now(),
    }
    start = time.perf_counter()
    try:
        with _sigterm_interrupts():
            _run_task(task, row, workshop)
    except KeyboardInterrupt:
        row["interrupted"] = True
        row["error"] = "interrupted"
    except BaseException as error:  # noqa: BLE001 - a failed run is a row, never the end
        # of the sweep: SystemExit from a user's plug-in included (re-raised in the parent
        # by the pool, it would end the sweep with no rows)
        message = " ".join(str(error).split())
        row["error"] = f"{type(error).__name__}: {message}"
    row["task_wall_s"] = time.perf_counter() - start
    row["finished_at"] = _now()
    return row


def execute_batch(tasks: Sequence[RunTask], on_row: RowSink) -> None:
    """Run ``tasks`` one after another in this process, handing each row to ``on_row`` as
    it finishes (a sweep worker hands it to the parent through a queue at once).

    One :class:`~cosim.simulation.workshop.Workshop` serves the whole batch: a task with the
    same car, filter or tracker as the one before it reuses them, reset, instead of
    building them again (about 0.2 s a run); every row is that of :func:`execute_task`
    alone. An interrupt ends the batch: the interrupted run's row is the last, and the
    tasks after it get none (they did not run; ``--resume`` runs them)."""
    from cosim.simulation.workshop import Workshop

    workshop = Workshop()
    try:
        with _sigterm_interrupts():  # also between two tasks
            for task in tasks:
                row = execute_task(task, workshop)
                on_row(row)
                if row["interrupted"]:
                    break
    except KeyboardInterrupt:
        pass  # between two tasks: the rows so far are the batch's


def batch_size(remaining: int, workers: int) -> int:
    """How many of the ``remaining`` tasks to hand a worker at once: a share that leaves
    every worker several more batches (so the sweep's end is balanced), at most
    :data:`MAX_BATCH`, at least one."""
    return max(1, min(MAX_BATCH, math.ceil(remaining / (BATCHES_PER_WORKER * workers))))


MAX_BATCH = 8
"""The most tasks one submission to a sweep worker holds: a worker builds its parts afresh
for each batch, and a batch in the pool can no longer be cancelled (eight 15-s runs are
some 20 s of work)."""

BATCHES_PER_WORKER = 3
"""Of the tasks left, each worker takes at most this fraction's inverse at a time, so the
batches shrink towards the end and the workers finish together."""


PRELOADED_MODULES = ("cosim.sweeps.execute", "cosim.simulation.runner",
                     "cosim.simulation.beliefs", "cosim.simulation.belief_check",
                     "tracker.mpc.kinematic_nmpc", "estimation.ekf")
"""What a forkserver imports before it forks the workers (:func:`pool_context`): the runner
and what a default run builds (the NMPC, the EKF); a module missing here is imported by the
worker that needs it, as a spawned worker imports everything."""


def pool_context() -> multiprocessing.context.BaseContext:
    """The start method of a sweep's worker processes: ``forkserver`` where the platform has
    it (Linux, macOS), the server importing :data:`PRELOADED_MODULES` once, else ``spawn``
    (module docstring). multiprocessing keeps one forkserver per process: every pool a
    process starts (a sweep's, an envelope's rounds, the pools that run a crashed batch's
    runs one by one) forks its workers from it."""
    if "forkserver" not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("spawn")
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(list(PRELOADED_MODULES))
    return context


def _init_worker(parent_pid: int, environment: dict[str, str]) -> None:
    """Pool worker start-up: the sweep's environment, one thread per numeric library; Ctrl-C
    is the parent's to handle.

    A worker forked from a forkserver has the server's environment, the sweep process's
    when the server started (the working directory and ``sys.path`` multiprocessing passes
    itself): ``environment`` is the sweep process's now, so a variable set since (a cache
    folder, a plug-in's setting) reaches the runs as it does a spawned worker.

    A terminal's Ctrl-C reaches every process of the group. An idle worker ignores it (no
    traceback from a worker waiting for work); a running run still stops on it, because
    :func:`cosim.simulation.runner.run` installs its own handler while it runs, and that row is then
    dropped as interrupted.
    """
    if os.environ != environment:
        os.environ.clear()
        os.environ.update(environment)
    for name in THREAD_LIMITS:
        os.environ.setdefault(name, "1")
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    drop_unraisable_interrupts()  # a SIGTERM in a weakref callback: no traceback
    die_with_parent(parent_pid)


def _interrupt(signum: int, frame: object) -> None:
    del signum, frame
    raise KeyboardInterrupt


@contextlib.contextmanager
def _sigterm_interrupts() -> Iterator[None]:
    """While a task runs, SIGTERM (the parent stopping its workers) is an interrupt, so a
    run still being set up ends its row as interrupted; an idle worker keeps the default
    (it ends quietly)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


STOP_GRACE_S = 0.8
"""After an interrupt, how long running workers get to finish their rows (SIGTERM: a run
stops between two physics steps and closes its log) before they are killed."""


PARENT_CHECK_S = 0.5
"""How often a sweep worker looks whether its parent is still there."""


def die_with_parent(sweep_pid: int) -> None:
    """End this worker when the sweep process ``sweep_pid`` that started it dies, even by
    SIGKILL (also when it died while this worker was still starting up).

    The worker's parent is the sweep process (``spawn``) or the forkserver the sweep process
    started, which lives on while any process it forked does (each holds the server's end
    of the sweep's pipe). Linux: ``prctl(PR_SET_PDEATHSIG, SIGKILL)`` (man 2 prctl) has the
    kernel kill the worker when its parent ends. Everywhere: a daemon thread watches the
    sweep process, on a pidfd (``os.pidfd_open``, Linux: woken the moment it ends) or
    looking every :data:`PARENT_CHECK_S`, and the parent's pid, and exits the process when
    the sweep process has ended or the worker been re-parented. Once the workers are gone,
    the forkserver and multiprocessing's resource tracker see their pipes close and end too.
    """
    if sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    parent = os.getppid()
    handle = _process_handle(sweep_pid)
    if parent != sweep_pid and not _alive(sweep_pid):  # it died before this worker got here
        os._exit(1)

    def sweep_running() -> bool:
        """Whether the sweep process is still there, after waiting up to PARENT_CHECK_S."""
        if handle is not None:
            return not select.select([handle], [], [], PARENT_CHECK_S)[0]
        time.sleep(PARENT_CHECK_S)
        return _alive(sweep_pid)

    def watch() -> None:
        while os.getppid() == parent and sweep_running():
            pass
        os._exit(1)

    threading.Thread(target=watch, name="cosim-parent-watch", daemon=True).start()


def _process_handle(pid: int) -> int | None:
    """A pidfd of process ``pid`` (readable once it has ended), where the platform has them;
    None elsewhere, or when it has ended already."""
    if not hasattr(os, "pidfd_open"):
        return None
    try:
        return os.pidfd_open(pid)
    except OSError:
        return None


def _alive(pid: int) -> bool:
    """Whether process ``pid`` exists (signal 0 checks without sending anything)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # it exists, owned by another user
        return True
    return True


PR_SET_PDEATHSIG = 1
"""``prctl`` option: the signal a process gets when its parent dies (linux/prctl.h)."""


RowSink = Callable[[dict[str, Any]], None]
"""Where a backend hands each finished row (the driver appends it to results.jsonl)."""


@dataclass(frozen=True)
class ProcessBackend:
    """Runs tasks on a pool of ``workers`` spawned processes on this machine."""

    workers: int

    def run(self, tasks: Sequence[RunTask], on_row: RowSink) -> None:
        """Run every task, calling ``on_row`` with each row as it finishes.

        A worker process that dies (``os._exit`` in a plug-in, a signal, out of memory, a
        crash in native code) breaks the pool and every batch in flight with it; their
        runs are then run again one at a time in a pool of their own, so the run that kills its
        worker alone becomes a row with that error (named, the others finish) and the
        remaining tasks go on in a fresh pool.

        On ``KeyboardInterrupt`` (Ctrl-C, or SIGTERM as the driver maps it, whether or not
        the workers got the signal too) no further task is handed to the pool and every
        worker is sent SIGTERM: its run stops between two physics steps and hands over its
        row (saying it was interrupted). Rows that land within :data:`STOP_GRACE_S` are
        handed over; workers still running then are killed, and the interrupt goes on. No
        worker outlives the call.
        """
        pending = list(tasks)
        while pending:
            suspects = _run_pool(pending, self.workers, on_row)
            for task in suspects:
                if _run_pool([task], 1, on_row):
                    on_row(_crashed_row(task, WorkerDiedError(
                        "its worker process died (os._exit, a signal, out of memory or a "
                        "crash in native code)")))


def _run_pool(pending: list[RunTask], workers: int, on_row: RowSink) -> list[RunTask]:
    """Run ``pending`` (consumed) on a fresh pool until it is empty or the pool breaks;
    return the tasks that were in flight when a worker died (none if none did).

    Each worker puts a row on a managed queue the moment its run ends (so the progress line
    and ``results.jsonl`` move run by run, and a worker that dies loses no row it finished);
    a batch's future only says that the batch is over."""
    context = pool_context()
    workers = max(1, min(workers, len(pending)))
    manager = SyncManager(ctx=context)
    manager.start(die_with_parent, (os.getpid(),))
    executor = concurrent.futures.ProcessPoolExecutor(
        max_workers=workers, mp_context=context, initializer=_init_worker,
        initargs=(os.getpid(), dict(os.environ)))
    rows = _RowQueue(manager.Queue(), on_row)
    # At most one batch per worker is handed to the pool: a batch in the pool's queue can
    # no longer be cancelled, so a deeper queue would run on after an interrupt.
    running: dict[concurrent.futures.Future[None], list[RunTask]] = {}
    broken: list[list[RunTask]] = []
    """Batches in flight when the pool broke; which of their runs finished is known only
    once every worker is gone and every queued row handed over (below)."""
    try:
        try:
            while (pending or running) and not broken:
                while pending and len(running) < workers:
                    size = batch_size(len(pending), workers)
                    batch, pending[:size] = pending[:size], []
                    try:
                        running[executor.submit(execute_batch, batch, rows.put)] = batch
                    except concurrent.futures.process.BrokenProcessPool:
                        pending[:0] = batch  # never started: it goes on in a fresh pool
                        break
                if not running:  # the pool broke with nothing in flight: start a fresh one
                    break
                done, _ = concurrent.futures.wait(
                    running, timeout=ROW_POLL_S, return_when=concurrent.futures.FIRST_COMPLETED)
                rows.hand_over()  # a batch's rows are all queued before its future is done
                for future in done:
                    batch = running.pop(future)
                    if isinstance(future.exception(),
                                  concurrent.futures.process.BrokenProcessPool):
                        broken.append(batch)
        except KeyboardInterrupt:
            _stop(executor, set(running), rows)
            raise
    finally:
        executor.shutdown(wait=True, cancel_futures=True)
        with contextlib.suppress(Exception):
            rows.hand_over()
        manager.shutdown()
    if broken:  # the runs still in flight went down with the pool
        for future, batch in running.items():
            if not (future.done() and future.exception() is None):
                broken.append(batch)
    # Only now, with the workers gone and their queued rows handed over: a run of a broken
    # batch whose row arrived is finished, and running it again would give it two rows.
    return sorted((task for batch in broken for task in rows.unfinished(batch)),
                  key=lambda task: task.run_id)


ROW_POLL_S = 0.1
"""How often the sweep process looks for rows its workers have queued."""


class _RowQueue:
    """The queue sweep workers put their rows on, and the parent's side of it: each row is
    handed to ``on_row`` once, and the run ids handed over are remembered so a broken
    batch's finished runs are not run again."""

    def __init__(self, queue: Any, on_row: RowSink) -> None:
        self.put: RowSink = queue.put
        self._queue = queue
        self._on_row = on_row
        self._handed: set[int] = set()

    def hand_over(self) -> None:
        """Hand every row queued so far to ``on_row``."""
        while True:
            try:
                row = self._queue.get_nowait()
            except queue_module.Empty:
                return
            if not row.get("interrupted"):  # a run stopped by the pool's end runs again
                self._handed.add(row["run_id"])
            self._on_row(row)

    def unfinished(self, batch: Sequence[RunTask]) -> list[RunTask]:
        """The tasks of ``batch`` whose rows have not been handed over."""
        return [task for task in batch if task.run_id not in self._handed]


class WorkerDiedError(CosimError):
    """A run's worker process died under it (the run's row carries this error)."""


def _stop(executor: concurrent.futures.ProcessPoolExecutor,
          running: set[concurrent.futures.Future[None]], rows: _RowQueue) -> None:
    """Stop the pool's workers after an interrupt (:meth:`ProcessBackend.run`)."""
    # The executor keeps its worker processes by pid; there is no public accessor before
    # Python 3.14's terminate_workers().
    workers = list(getattr(executor, "_processes", {}).values())
    for worker in workers:
        with contextlib.suppress(OSError, ValueError):
            if worker.pid is not None:
                os.kill(worker.pid, signal.SIGTERM)
    concurrent.futures.wait(running, timeout=STOP_GRACE_S)
    rows.hand_over()
    for worker in workers:
        with contextlib.suppress(OSError, ValueError):
            if worker.is_alive():
                worker.kill()
    for future in running:
        future.cancel()


@dataclass(frozen=True)
class RayBackend:
    """Runs tasks as Ray tasks (one CPU each) on a local Ray or a cluster.

    ``address``: the cluster to join (``ray://host:10001`` or ``host:6379``); ``None`` uses
    ``RAY_ADDRESS`` if set, else starts a local Ray. ``workers`` caps the tasks in flight
    (``None``: as many as Ray schedules). Every node needs cosim installed in the same
    version: a task imports :mod:`cosim` on the node that runs it.
    """

    address: str | None
    workers: int | None

    def run(self, tasks: Sequence[RunTask], on_row: RowSink) -> None:
        """Run every task, calling ``on_row`` with each row as it finishes.

        A task whose worker dies becomes a row with its error. On ``KeyboardInterrupt`` the
        tasks in flight are cancelled and the interrupt goes on.
        """
        ray = import_ray()
        if not tasks:
            return
        address = self.address or os.environ.get("RAY_ADDRESS") or None
        started_here = not ray.is_initialized()
        if started_here:
            ray.init(address=address, logging_level="ERROR", log_to_driver=False)
        remote = ray.remote(num_cpus=1, max_retries=0)(execute_task)
        pending = list(tasks)
        limit = len(pending) if self.workers is None else self.workers
        in_flight: dict[Any, RunTask] = {}
        try:
            while pending or in_flight:
                while pending and len(in_flight) < limit:
                    task = pending.pop(0)
                    in_flight[remote.remote(task)] = task
                done, _ = ray.wait(list(in_flight), num_returns=1)
                for ref in done:
                    task = in_flight.pop(ref)
                    try:
                        row = ray.get(ref)
                    except ray.exceptions.RayError as error:
                        row = _crashed_row(task, error)
                    on_row(row)
        finally:
            for ref in in_flight:
                ray.cancel(ref, force=True)
            if started_here:
                ray.shutdown()


def _crashed_row(task: RunTask, error: Exception) -> dict[str, Any]:
    first_line = (str(error).strip().splitlines() or [""])[0]
    return {"run_id": task.run_id, "point": task.point, "seed": task.seed,
            "params": dict(task.params), "metrics": {}, "interrupted": False,
            "error": f"{type(error).__name__}: {first_line}", "log": task.log_path or "",
            "started_at": _now(), "task_wall_s": None, "finished_at": _now()}


def import_ray() -> Any:
    """The ``ray`` module, or a :class:`CosimError` saying how to install it."""
    try:
        import ray
    except ImportError:
        raise CosimError("--backend ray: Ray is not installed: expected it from "
                         "`pip install '.[ray]'` (or `pip install ray`)") from None
    return ray


def make_backend(name: str, workers: int | None, ray_address: str | None
                 ) -> ProcessBackend | RayBackend:
    """The backend called ``name`` (``process`` or ``ray``)."""
    if workers is not None and workers < 1:
        raise CosimError(f"--workers {workers}: expected a count >= 1")
    if name == "process":
        return ProcessBackend(workers if workers is not None else default_workers())
    if name == "ray":
        import_ray()  # fail before any work, with the install hint
        return RayBackend(ray_address, workers)
    raise CosimError(f"--backend {name!r}: expected process or ray")
