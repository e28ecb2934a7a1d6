"""The figures of `cosim plot` drawn on two cores.

Each figure is independent of the others once the logs are read (:mod:`cosim.plots.data`),
and drawing one is matplotlib's work alone (layout, rasterising, PNG encoding: 0.3-1.5 s a
figure). :func:`draw` hands every other figure to a forked copy of this process, which
has the logs already in memory (nothing is read, pickled or imported again), and draws
the rest itself: the figures come out as one process would write them, byte for byte
(``tests/plots/test_plot.py``), in about half the time on a machine with a second core.
Where there is no second core, or not Linux (Windows has no ``fork``; on macOS a forked
copy of a process that has loaded Apple's frameworks may be stopped by them), every figure
is drawn here, one after another.
"""

from __future__ import annotations

import multiprocessing
import os
import pickle
import sys
import traceback
from collections.abc import Callable, Sequence
from multiprocessing.connection import Connection
from pathlib import Path

from cosim.core.exceptions import CosimError

FigureJob = Callable[[], Path | None]
"""Draws one figure and returns its file (None: the logs have nothing for it)."""


def cores() -> int:
    """The cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def draw(jobs: Sequence[FigureJob], processes: int | None = None) -> list[Path | None]:
    """Every job's result, in the jobs' order. ``processes``: at most this many processes
    draw (None: two where there are two cores; 1: this process alone). A job that raises
    raises here, the same exception where it can be sent back (else a
    :class:`CosimError` with its traceback); a forked process that dies is a
    :class:`CosimError` naming its exit code."""
    processes = min(2, cores()) if processes is None else processes
    if processes < 2 or len(jobs) < 2 or not sys.platform.startswith("linux"):
        return [job() for job in jobs]
    theirs, ours = list(range(0, len(jobs), 2)), list(range(1, len(jobs), 2))
    context = multiprocessing.get_context("fork")
    receive, send = context.Pipe(duplex=False)
    child = context.Process(target=_draw_and_send, args=([jobs[i] for i in theirs], send),
                            name="cosim-plot", daemon=True)
    child.start()
    send.close()
    results: list[Path | None] = [None] * len(jobs)
    try:
        for i in ours:
            results[i] = jobs[i]()
    finally:  # the child's answer is awaited even when a figure of ours failed
        answer = _receive(receive, child)
    for i, result in zip(theirs, answer, strict=True):
        results[i] = result
    return results


def _draw_and_send(jobs: list[FigureJob], send: Connection) -> None:
    """In the forked process: draw ``jobs`` and send their results, or the exception."""
    try:
        message: tuple[str, object] = ("drawn", [job() for job in jobs])
    except BaseException as error:  # noqa: BLE001 (sent to the parent, which raises it)
        message = ("failed", _portable(error))
    send.send(message)
    send.close()


def _portable(error: BaseException) -> BaseException:
    """``error`` if it survives pickling, else a :class:`CosimError` with its traceback."""
    try:
        pickle.loads(pickle.dumps(error))
    except Exception:  # noqa: BLE001 (any failure to pickle: sent as text)
        return CosimError("drawing a figure failed:\n" + "".join(
            traceback.format_exception(error)).rstrip())
    return error


def _receive(receive: Connection, child: multiprocessing.process.BaseProcess
             ) -> list[Path | None]:
    """The forked process's results (its exception raised here)."""
    try:
        kind, payload = receive.recv()
    except EOFError:
        child.join()
        raise CosimError(f"the process drawing half of the figures died (exit code "
                         f"{child.exitcode}): some of them may be missing") from None
    finally:
        receive.close()
    child.join()
    if kind == "failed":
        assert isinstance(payload, BaseException)
        raise payload
    assert isinstance(payload, list)
    return payload
