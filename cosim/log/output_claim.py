"""Claiming a log's name for one run, so that two runs on one ``--out`` cannot both write it.

A log is written under a temporary name and renamed to its final name once the run has
started (:mod:`cosim.log.safe_file`), so the final name's absence proves nothing while
another run is still setting up: two runs started together on one ``--out`` both passed
the "exists" check, both ran, and the second rename silently replaced the first log.

:func:`claim_output` therefore takes an exclusive lock on a lock file beside the final name
(``.NAME.lock``, ``flock(2)`` via :func:`fcntl.flock`) before the run starts and holds it
until the log is finished. A second run on the same name finds it locked and is refused
(:class:`~cosim.core.exceptions.ConfigError`: one line, exit code 2) before it builds
anything. The checks of :func:`~cosim.log.safe_file.check_output_path` (an existing file
without ``--force``, a folder, an input file) run under the lock, so a run that finished
just before is seen too.

The kernel drops a ``flock`` when its holder dies, even by SIGKILL, so a killed run leaves
no stale claim: at worst an unlocked ``.NAME.lock`` file, which the next run takes over. The
holder removes the lock file on release; a run that opened the old file just before may
hold a lock on a file no longer in the folder, so a claim re-checks, once locked, that its
file is still the one at the lock's path (and starts over if not).
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterable, Iterator
from pathlib import Path

from cosim.core.exceptions import ConfigError
from cosim.log.safe_file import check_output_path

try:
    import fcntl
except ImportError:  # not POSIX: the lock file is made exclusively instead
    fcntl = None  # type: ignore[assignment]


def lock_path(path: Path) -> Path:
    """The lock file of the log ``path``: ``.NAME.lock`` beside it."""
    return path.with_name(f".{path.name}.lock")


def _open_locked(lock: Path) -> int | None:
    """A descriptor of ``lock`` holding its exclusive lock; None when another holds it."""
    if fcntl is None:
        try:
            return os.open(lock, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o644)
        except FileExistsError:
            return None
    while True:
        descriptor = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(descriptor, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(descriptor)
            return None
        except BaseException:
            os.close(descriptor)
            raise
        try:  # still the file at that name (the last holder may have removed it)?
            same = os.path.samestat(os.fstat(descriptor), os.stat(lock))
        except FileNotFoundError:
            same = False
        if same:
            return descriptor
        os.close(descriptor)


class OutputTakenError(ConfigError):
    """Another run holds the log's name (:func:`claim_output`)."""


@contextlib.contextmanager
def claim_output(path: Path, option: str, force: bool,
                 inputs: Iterable[str | Path | None] = ()) -> Iterator[Path]:
    """Hold ``path`` for this run: locked, then checked as
    :func:`~cosim.log.safe_file.check_output_path` checks it. Refused in one line when
    another run holds it; released (the lock file removed) when the block ends."""
    path = Path(path)
    check_output_path(path, option, force, inputs)  # a folder, an input: before any file
    lock = lock_path(path)
    try:
        lock.parent.mkdir(parents=True, exist_ok=True)
        descriptor = _open_locked(lock)
    except OSError as error:
        raise ConfigError(f"{option} {str(path)!r}: cannot write ({error.strerror or error}): "
                          "expected a writable place") from None
    if descriptor is None:
        raise OutputTakenError(f"{option} {str(path)!r}: another cosim run is writing it now: "
                          "expected another file name (or wait for that run to end)")
    try:
        check_output_path(path, option, force, inputs)  # under the lock: a run just ended
        yield path
    finally:
        with contextlib.suppress(OSError):
            lock.unlink()
        os.close(descriptor)
