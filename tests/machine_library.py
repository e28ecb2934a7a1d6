"""A fresh cache of compiled libraries that holds the machine's library of one build alone.

The tests of "one library serves every belief" need a cache no other test writes to (two
test processes share the machine's): they build the default belief's library in the
machine's cache, where every other test of the same model finds it too (so a fresh
machine compiles it once, not once for those tests and again for this one), copy that one
entry into a cache of their own, and count what the other beliefs add there: nothing but
the hash each recipe keeps (:mod:`cosim.core.built_on_disk`), no library, no note."""

from __future__ import annotations

import contextlib
import shutil
from collections.abc import Callable, Iterator
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

from cosim.core import compiled_function
from cosim.core.compiled_cache import cache_dir


@contextlib.contextmanager
def libraries_built(*modules: ModuleType) -> Iterator[list[Path]]:
    """The paths :func:`cosim.core.compiled_function.compiled_library` returns while the
    block runs, called from :mod:`cosim.core.compiled_function` itself or from each of
    ``modules`` (which import it by name)."""
    found: list[Path] = []
    with pytest.MonkeyPatch.context() as patch:
        for module in (compiled_function, *modules):
            real: Callable[..., Path | None] = module.compiled_library

            def spy(*args: Any, real: Callable[..., Path | None] = real,
                    **kwargs: Any) -> Path | None:
                path = real(*args, **kwargs)
                if path is not None:
                    found.append(path)
                return path

            patch.setattr(module, "compiled_library", spy)
        yield found


def fresh_cache_with(library: Path, monkeypatch: pytest.MonkeyPatch, folder: Path) -> Path:
    """Point the cache at ``folder`` (``XDG_CACHE_HOME``) holding a copy of the machine
    cache's entry of ``library`` alone; the new cache's folder."""
    entry = library.parent
    assert entry.parent == cache_dir(), f"{library} is not in the machine's cache"
    monkeypatch.setenv("XDG_CACHE_HOME", str(folder))
    shutil.copytree(entry, cache_dir() / entry.name)
    return cache_dir()
