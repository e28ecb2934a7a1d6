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
import functools
import hashlib
import json
import os
import shutil
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from cosim.core.exceptions import ConfigError

try:
    import fcntl
except ImportError:  # not POSIX: builds are not serialised (the first to install wins)
    fcntl = None  # type: ignore[assignment]

MANIFEST = "manifest.json"
"""The file beside each library with its size and SHA-256, checked before every load."""

DEFAULT_LIMIT_MB = 1024.0
"""The cache's bound unless ``COSIM_CACHE_MAX_MB`` says otherwise."""


def cache_dir() -> Path:
    """``$XDG_CACHE_HOME/cosim`` (``~/.cache/cosim``)."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "cosim"


def private_folder(pid: int | None = None) -> Path:
    """Where process ``pid`` (this one by default) keeps the libraries the cache could not
    take (an unwritable cache): a folder of its own in the temporary directory, removed at
    the process's exit, and by `cosim run`'s guard (:mod:`cosim.cli.guard`) when the run's
    process ends without Python's exit handlers (``os._exit``, a signal)."""
    return Path(tempfile.gettempdir()) / f"cosim-compiled-{os.getpid() if pid is None else pid}"


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


def file_digest(path: Path) -> str:
    """The SHA-256 of the file at ``path`` (hex)."""
    sha = hashlib.sha256()
    with path.open("rb") as stream:
        for block in iter(lambda: stream.read(1 << 20), b""):
            sha.update(block)
    return sha.hexdigest()


@functools.lru_cache(maxsize=64)
def _checked_digest(path: str, size: int, mtime_ns: int, inode: int) -> str:
    """:func:`file_digest` of the file at ``path``, computed once per process for each
    version of it (its size, modification time and inode name the version: a file
    rewritten, truncated or replaced is hashed again). A run's libraries are checked at
    every run's set-up; hashing the NLP's 2 MB again each time cost a millisecond a run."""
    del size, mtime_ns, inode  # part of the key only
    return file_digest(Path(path))


def entry_damage(entry: Path, filename: str, what: str = "the library") -> str:
    """Why the cache entry ``entry`` cannot be used ("" when its file ``filename``, called
    ``what`` in the answer, has the size and SHA-256 its manifest gives)."""
    data = entry / filename
    try:  # a hand-edited manifest: size Infinity, nesting deep enough to recurse ...
        manifest = json.loads((entry / MANIFEST).read_text())
        size, digest = int(manifest["size"]), str(manifest["sha256"])
    except (OSError, ValueError, KeyError, TypeError, OverflowError, RecursionError):
        return f"its {MANIFEST} is missing or unreadable"
    try:
        actual = data.stat()
    except OSError:
        return f"{what} is missing"
    if actual.st_size != size:
        return f"{what} has {actual.st_size} bytes, {size} were written"
    if _checked_digest(str(data), actual.st_size, actual.st_mtime_ns, actual.st_ino) != digest:
        return f"{what}'s SHA-256 differs from the one written"
    return ""


def install(built: Path, entry: Path, filename: str) -> Path:
    """Put the file ``built`` into the cache as ``entry`` (a folder with the file, named
    ``filename``, and its manifest), atomically: written under a temporary name and
    renamed, so a concurrent run sees either no entry or a whole one. Another run that
    installed first wins. The installed file's path."""
    entry.parent.mkdir(parents=True, exist_ok=True)
    staging = entry.with_name(f".{entry.name}.{os.getpid()}.tmp")
    shutil.rmtree(staging, ignore_errors=True)
    staging.mkdir()
    try:
        shutil.copyfile(built, staging / filename)
        manifest = {"size": built.stat().st_size, "sha256": file_digest(built)}
        (staging / MANIFEST).write_text(json.dumps(manifest))
        try:
            os.rename(staging, entry)
        except OSError:
            if not entry.is_dir():
                raise
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return entry / filename


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
