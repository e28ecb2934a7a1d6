"""The folder of compiled libraries (:mod:`cosim.core.compiled_function`): where it is, what
it holds, and how it is kept from growing without bound.

Each entry is a folder ``NAME-HASH`` holding one library and its manifest (size and SHA-256
of the library). An entry is used by every run that needs its library, so a use marks it
(the manifest's modification time, :func:`mark_used`); once the folder holds more than
:func:`limit_bytes` (``COSIM_CACHE_MAX_MB``, 1024 MB by default), the entries used least
recently are removed until it is under the limit again (:func:`prune`), at the next build.
A library a run has loaded stays mapped in that run when its file is removed, so pruning
or clearing never breaks a running process; the next run that needs the entry builds it
again. ``cosim cache`` shows the folder and ``cosim cache --clear`` empties it.
"""

from __future__ import annotations

import contextlib
import os
import shutil
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from cosim.core.exceptions import ConfigError

try:
    import fcntl
except ImportError:  # not POSIX: builds are not serialised (the first to install wins)
    fcntl = None  # type: ignore[assignment]

MANIFEST = "manifest.json"
"""The file beside each library with its size and SHA-256."""

DEFAULT_LIMIT_MB = 1024.0
"""The cache's bound unless ``COSIM_CACHE_MAX_MB`` says otherwise."""


def cache_dir() -> Path:
    """``$XDG_CACHE_HOME/cosim`` (``~/.cache/cosim``)."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "cosim"


def limit_bytes() -> int:
    """The cache's bound in bytes: ``COSIM_CACHE_MAX_MB`` (a number of megabytes > 0)."""
    text = os.environ.get("COSIM_CACHE_MAX_MB")
    if text is None:
        return int(DEFAULT_LIMIT_MB * 1e6)
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (value > 0.0 and value < 1e9):
        raise ConfigError(f"COSIM_CACHE_MAX_MB = {text!r}: expected a number of megabytes > 0")
    return int(value * 1e6)


@dataclass(frozen=True)
class Entry:
    """One cached library."""

    path: Path
    size_bytes: int
    used_s: float
    """When a run last used it (seconds since the epoch)."""

    @property
    def name(self) -> str:
        """The library's name (the folder's name without its hash)."""
        return self.path.name.rsplit("-", 1)[0]


def entries(folder: Path | None = None) -> list[Entry]:
    """The cache's entries (folders that are not being written or removed), least recently
    used first."""
    folder = cache_dir() if folder is None else folder
    found = []
    with contextlib.suppress(OSError):
        for path in folder.iterdir():
            if path.name.startswith(".") or not path.is_dir():
                continue
            size, used = 0, 0.0
            with contextlib.suppress(OSError):
                size = sum(f.stat().st_size for f in path.iterdir() if f.is_file())
                used = (path / MANIFEST).stat().st_mtime
            found.append(Entry(path, size, used))
    return sorted(found, key=lambda e: (e.used_s, e.path.name))


@contextlib.contextmanager
def build_lock(entry: Path) -> Iterator[None]:
    """Hold the lock of building ``entry`` (``flock(2)`` on ``.NAME-HASH.lock`` beside it,
    removed on release): a second process waits until the first has built it. Where the
    folder cannot be written or locks do not exist, nothing is held (the build goes on; the
    first to install wins)."""
    lock = entry.with_name(f".{entry.name}.lock")
    descriptor = _locked(lock)
    try:
        yield
    finally:
        if descriptor is not None:
            with contextlib.suppress(OSError):
                lock.unlink()
            os.close(descriptor)  # closing releases the lock


def _locked(lock: Path) -> int | None:
    """A descriptor holding ``lock``'s exclusive lock (waiting for it), or None."""
    if fcntl is None:
        return None
    while True:
        try:
            lock.parent.mkdir(parents=True, exist_ok=True)
            descriptor = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError:
            return None
        try:
            fcntl.flock(descriptor, fcntl.LOCK_EX)
            same = os.path.samestat(os.fstat(descriptor), os.stat(lock))
        except OSError:  # removed by its last holder meanwhile: take the new one
            same = False
        if same:
            return descriptor
        os.close(descriptor)


def mark_used(entry: Path) -> None:
    """Note that a run uses ``entry`` now (its manifest's modification time)."""
    with contextlib.suppress(OSError):
        os.utime(entry / MANIFEST)


def remove(entry: Path) -> None:
    """Remove an entry (renamed away first, so no other process loads it half-gone)."""
    trash = entry.with_name(f".{entry.name}.{os.getpid()}.trash")
    with contextlib.suppress(OSError):
        os.rename(entry, trash)
    shutil.rmtree(trash, ignore_errors=True)


def prune(keep: Path | None = None, limit: int | None = None) -> list[Entry]:
    """Remove the least recently used entries until the cache holds at most ``limit`` bytes
    (:func:`limit_bytes`), never ``keep`` (the entry just built); the removed entries."""
    limit = limit_bytes() if limit is None else limit
    found = entries()
    total = sum(e.size_bytes for e in found)
    removed = []
    for entry in found:
        if total <= limit:
            break
        if keep is not None and entry.path == keep:
            continue
        remove(entry.path)
        total -= entry.size_bytes
        removed.append(entry)
    return removed


def clear() -> list[Entry]:
    """Remove every entry; the removed entries."""
    found = entries()
    for entry in found:
        remove(entry.path)
    return found
