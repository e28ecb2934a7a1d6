"""A pure builder's result kept on disk, so that a new process reads it instead of
building it again.

Some of a run's set-up is a pure function of its arguments and of the code: the sedan's
MJCF text, for one, which dm_control's PyMJCF writes in some 70 ms a process (its import
included) for a text MuJoCo then compiles in a few. :func:`kept_on_disk` writes such a
result (JSON) once into the cache folder, beside the compiled libraries
(:mod:`cosim.core.compiled_cache`: an entry ``NAME-HASH`` holding the data and its
manifest, within the same bound, shown and cleared by ``cosim cache``; at most
:data:`KEPT_PER_NAME` of a name, those used last), named by a hash of

* the builder's arguments, as their ``repr`` (frozen dataclasses of numbers and strings:
  a float's ``repr`` is exact, so equal arguments and only those give equal text);
* the code (:func:`code_stamp`): the path, size and modification time of every source and
  model file of the project and of the third-party packages the caller names.

Editing any of those files, installing another version of a package or passing other
arguments gives another name, whose result is built afresh; nothing is ever looked up by a
key that could hold a stale result. An entry is checked before use as a library is (its
data's size and SHA-256); a damaged one is removed and built again, and where the cache
cannot be written the result is simply built, as without it.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import importlib.util
import json
import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

from cosim.core.compiled_cache import (
    MANIFEST,
    cache_dir,
    entry_damage,
    install,
    mark_used,
    remove,
)

PROJECT_PACKAGES = ("cosim", "estimation", "tracker")
"""The project's packages, whose files are part of every key (:func:`code_stamp`)."""

KEPT_PER_NAME = 256
"""Entries kept per name (the sedan's texts of as many cars, steps and code versions): a
new one replaces the one used least recently; the cache's byte bound holds as well."""

STAMPED_SUFFIXES = (".py", ".c", ".h", ".xml", ".yaml", ".json")
"""The files of a package whose path, size and modification time the stamp holds."""


def kept_on_disk(name: str, arguments: str, build: Callable[[], Any],
                 packages: tuple[str, ...] = (), folders: tuple[Path, ...] = (),
                 valid: Callable[[Any], bool] = lambda value: True) -> Any:
    """``build()``'s result (a JSON value) for ``arguments`` (the ``repr`` of everything
    the builder reads besides the code), read from the cache entry ``name-HASH`` when an
    earlier process wrote it, else built and written there. ``packages`` names the
    third-party packages (import names) whose files the result depends on besides the
    project's own; ``folders`` further folders of data files it reads (the models).
    ``valid`` says whether a value read back has the builder's form: one that has not (an
    entry written by hand, manifest and all) is built again, as a damaged one is."""
    entry, filename = _entry(name, arguments, packages, folders)
    kept = _read(entry, filename, valid)
    if kept is not None:
        return kept[0]
    value = build()
    _write(entry, filename, value)
    return value


def kept_before(name: str, arguments: str, packages: tuple[str, ...] = (),
                folders: tuple[Path, ...] = (),
                valid: Callable[[Any], bool] = lambda value: True) -> tuple[Any] | None:
    """What :func:`kept_on_disk` with these arguments would read, as a 1-tuple, without
    building anything: None when no earlier process kept it (or its entry is damaged)."""
    return _read(*_entry(name, arguments, packages, folders), valid)


def _entry(name: str, arguments: str, packages: tuple[str, ...],
           folders: tuple[Path, ...]) -> tuple[Path, str]:
    """The cache entry of ``name`` for ``arguments`` and the code, and its data file."""
    stamp = code_stamp(tuple(packages), tuple(str(folder) for folder in folders))
    digest = hashlib.sha256(f"{name}\n{stamp}\n{arguments}".encode()).hexdigest()
    return cache_dir() / f"{name}-{digest[:32]}", f"{name}.json"


def _read(entry: Path, filename: str, valid: Callable[[Any], bool]) -> tuple[Any] | None:
    """The value of an intact entry, as a 1-tuple (the value may be None); None when there
    is no entry or it is damaged (then removed, for the next write)."""
    if not entry.is_dir():
        return None
    if not entry_damage(entry, filename, "the data"):
        try:
            value = json.loads((entry / filename).read_text(encoding="utf-8"))
        except (OSError, ValueError, RecursionError):
            pass
        else:
            if valid(value):
                mark_used(entry)
                return (value,)
    remove(entry)
    return None


def _write(entry: Path, filename: str, value: Any) -> None:
    """Install ``value`` as the entry (atomically; nothing when the cache cannot be
    written: the next process builds it again), and keep the :data:`KEPT_PER_NAME` entries
    of its name used last."""
    with contextlib.suppress(OSError), tempfile.TemporaryDirectory(
            prefix="cosim-kept-") as folder:
        built = Path(folder) / filename
        built.write_text(json.dumps(value), encoding="utf-8")
        install(built, entry, filename)
        _prune_name(entry)


def _prune_name(entry: Path, limit: int | None = None) -> None:
    """Remove the entries of ``entry``'s name used least recently beyond ``limit``
    (:data:`KEPT_PER_NAME`), never ``entry`` itself. Only that name's entries are looked
    at: the whole cache's bound (:func:`cosim.core.compiled_cache.prune`, which stats every
    entry, some 20 us each) is kept by the library builds, and run at every write of these
    small entries it cost 33 ms a write once the folder held 1,400 entries."""
    limit = KEPT_PER_NAME if limit is None else limit
    name = entry.name.rsplit("-", 1)[0]
    used = []
    for other in entry.parent.glob(f"{name}-*"):
        if other != entry and other.name.rsplit("-", 1)[0] == name:
            with contextlib.suppress(OSError):
                used.append(((other / MANIFEST).stat().st_mtime, other.name, other))
    used.sort()
    for _, _, other in used[:max(len(used) - (limit - 1), 0)]:
        remove(other)


@functools.lru_cache(maxsize=8)
def code_stamp(packages: tuple[str, ...] = (), folders: tuple[str, ...] = ()) -> str:
    """A hash of the path, size and modification time (ns) of every file with a suffix of
    :data:`STAMPED_SUFFIXES` in the project's packages, in ``packages`` (import names,
    found without importing them) and in ``folders``: any edit, reinstall or upgrade
    changes it. Once per process (about a millisecond): files edited while a process runs
    are seen by the next one, as imports are."""
    lines: list[str] = []
    for package in (*PROJECT_PACKAGES, *packages):
        spec = importlib.util.find_spec(package)
        locations = [] if spec is None else list(spec.submodule_search_locations or ())
        lines.append(f"package {package}: {locations}")
        for location in locations:
            _stat_lines(location, lines)
    for folder in folders:
        lines.append(f"folder {folder}")
        _stat_lines(folder, lines)
    return hashlib.sha256("\n".join(sorted(lines)).encode()).hexdigest()


def _stat_lines(folder: str, lines: list[str]) -> None:
    """One line per stamped file under ``folder`` (recursively, caches left out)."""
    try:
        with os.scandir(folder) as found:
            for item in found:
                if item.is_dir(follow_symlinks=False):
                    if item.name != "__pycache__":
                        _stat_lines(item.path, lines)
                elif item.name.endswith(STAMPED_SUFFIXES):
                    status = item.stat()
                    lines.append(f"{item.path} {status.st_size} {status.st_mtime_ns}")
    except OSError as error:  # unreadable: part of the stamp as such
        lines.append(f"{folder} unreadable {error.errno}")
