"""What every ``cosim`` command shares: exit codes, the one-line parser, tables and lines.

The exit codes are a stable interface (scripts and outside tests rely on them): 0 done, 1 a
file or a standard stream could not be written, 2 bad input, 3 a run ended badly or a
``--fail-if`` holds, 130 an interrupt.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import sys
from collections.abc import Callable
from typing import Any, NoReturn

EXIT_USAGE = 2
EXIT_IO = 1
EXIT_BAD_OUTCOME = 3
EXIT_INTERRUPT = 130

Handler = Callable[[argparse.Namespace], int]
"""A command: its parsed arguments in, its exit code out."""


BLAS_THREADS_VARIABLE = "OPENBLAS_NUM_THREADS"
"""The environment variable that sets how many threads numpy's OpenBLAS starts."""


def single_threaded_blas() -> None:
    """One OpenBLAS thread for this command's process and every process it starts (the
    guarded run's child, a sweep's workers), unless the user set
    :data:`BLAS_THREADS_VARIABLE` already; call it before numpy is imported.

    OpenBLAS starts a thread per core when numpy is imported, and each busy-waits for work
    for a while before it sleeps: on two cores, 0.05-0.1 s of the other core's time at
    every process start, taken from whatever else runs there (a sweep's other worker, the
    other half of ``make test``: the suite 305 -> 301 s and 323 -> 312 s in two interleaved
    pairs, 7 and 22 s less CPU). None of that work is ever handed to them: a run's matrices
    are a few dozen rows at most, below OpenBLAS's threshold for threads, and the run
    limits BLAS to one thread anyway (:func:`cosim.simulation.runner.run`)."""
    os.environ.setdefault(BLAS_THREADS_VARIABLE, "1")


class Parser(argparse.ArgumentParser):
    """argparse, but a usage error is one line (not usage + error) and exit code 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message}\n")


def add_pool_options(parser: argparse.ArgumentParser) -> None:
    """``--workers``, ``--backend`` and the refused ``--live`` of a command that runs many
    runs on a pool (``cosim sweep``, ``cosim envelope``)."""
    parser.add_argument("--workers", type=int, metavar="N",
                        help="parallel runs (default: the number of cores)")
    parser.add_argument("--backend", choices=("process", "ray"), default="process",
                        help="process pool on this machine (default) or Ray")
    parser.add_argument("--live", action="store_true", help=argparse.SUPPRESS)


def refuse_live(args: argparse.Namespace, command: str) -> None:
    """``--live`` streams a single run: refused for a command that makes many."""
    if args.live:
        from cosim.core.exceptions import CosimError

        raise CosimError(f"cosim {command} --live: only a single run streams; expected "
                         "`cosim run SCENARIO --live` for the case you want to watch")


def format_value(value: Any) -> str:
    """A metric's value for a table: 4 significant digits, ``n/a`` for NaN and None."""
    if isinstance(value, bool) or value is None:
        return {True: "true", False: "false", None: "n/a"}[value]
    if isinstance(value, float):
        return "n/a" if not math.isfinite(value) else f"{value:.4g}"
    return str(value)


def print_table(title: str, rows: list[tuple[str, str]]) -> None:
    """Two columns (key, value): a rich table on a terminal, plain aligned text otherwise."""
    if sys.stdout.isatty():
        from rich.console import Console
        from rich.table import Table

        table = Table(title=title)
        table.add_column("metric")
        table.add_column("value", justify="right")
        for key, value in rows:
            table.add_row(key, value)
        Console().print(table)
        return
    width = max(len(key) for key, _ in rows)
    print(title)
    for key, value in rows:
        print(f"  {key:<{width}}  {value}")


def json_ready(values: dict[str, Any]) -> dict[str, Any]:
    """``values`` with NaN and infinity as None (JSON has neither)."""
    return {k: (None if isinstance(v, float) and not math.isfinite(v) else v)
            for k, v in values.items()}


def one_line_warning(message: Warning | str, category: type[Warning], filename: str,
                     lineno: int, file: Any = None, line: str | None = None) -> None:
    """A warning as one line on stderr (``cosim: warning: ...``), without source lines."""
    print(f"cosim: warning: {message}", file=sys.stderr)


def say(line: str) -> None:
    """One line on stderr, even when stderr itself is gone."""
    with contextlib.suppress(OSError):
        print(line, file=sys.stderr, flush=True)


def silence_stdout() -> None:
    """Point stdout at /dev/null so that Python's exit does not fail flushing it again."""
    with contextlib.suppress(OSError, ValueError):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
