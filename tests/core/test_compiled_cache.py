"""The cache of compiled CasADi functions is checked before every load: a damaged entry is
rebuilt once with a one-line warning, an unwritable cache is worked around for the run."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import warnings
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from cosim.core.compiled_cache import MANIFEST
from cosim.core.compiled_function import (
    CompiledCacheWarning,
    CompiledFunction,
    compile_function,
    compiled_library,
)

COSIM = str(Path(sys.executable).with_name("cosim"))


def _function(name: str = "cache_probe") -> ca.Function:
    x = ca.SX.sym("x", 2)
    return ca.Function(name, [x], [ca.vertcat(x[0] * x[1], x[0] + 3.0)])


def _evaluates_right(library: object, function: ca.Function) -> bool:
    inputs, outputs = [np.array([2.0, 5.0])], [np.zeros(2)]
    CompiledFunction(library, function, inputs, outputs)()
    return bool(np.array_equal(outputs[0], [10.0, 5.0]))


@pytest.fixture()
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    return tmp_path / "cache" / "cosim"


def _load_quietly(function: ca.Function) -> object:
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a healthy cache says nothing
        return compile_function(function)


def test_an_entry_is_a_library_with_its_size_and_hash(cache: Path) -> None:
    function = _function()
    library = _load_quietly(function)
    assert library is not None and _evaluates_right(library, function)
    (entry,) = cache.iterdir()
    manifest = json.loads((entry / MANIFEST).read_text())
    assert manifest["size"] == (entry / "cache_probe.so").stat().st_size
    stamp = (entry / "cache_probe.so").stat().st_mtime_ns
    found = compiled_library("cache_probe", [function], key=function.serialize())
    assert found == entry / "cache_probe.so"
    assert (entry / "cache_probe.so").stat().st_mtime_ns == stamp  # found, not rebuilt
    assert not [p for p in cache.iterdir() if p.name.startswith(".")]  # no temporaries


def test_a_keyed_entry_is_found_without_generating_its_source(cache: Path) -> None:
    # With a key, the functions are made (and their C generated) only to build the entry.
    function, made = _function(), []

    def functions() -> list[ca.Function]:
        made.append(1)
        return [function]

    first = compiled_library("cache_probe", functions, key="probe v1")
    assert first is not None and made == [1]
    assert compiled_library("cache_probe", functions, key="probe v1") == first
    assert made == [1]
    other = compiled_library("cache_probe", functions, key="probe v2")  # another key: built
    assert other is not None and other != first and made == [1, 1]


@pytest.mark.parametrize("damage", ["truncated", "another library", "garbage", "no manifest"])
def test_a_damaged_entry_is_rebuilt_once_with_a_warning(cache: Path, damage: str) -> None:
    function = _function()
    # Made, not loaded: damaging a library this process has mapped would end the test
    # itself with SIGBUS (the very failure the check keeps other runs from).
    assert compiled_library("cache_probe", [function], key=function.serialize()) is not None
    (entry,) = cache.iterdir()
    library = entry / "cache_probe.so"
    if damage == "truncated":
        library.write_bytes(library.read_bytes()[: library.stat().st_size // 2])
    elif damage == "another library":
        other = compiled_library("other_probe", [_function("other_probe")])
        assert other is not None
        library.write_bytes(other.read_bytes())
    elif damage == "garbage":
        library.write_bytes(os.urandom(library.stat().st_size))
    else:
        (entry / MANIFEST).unlink()
    with pytest.warns(CompiledCacheWarning, match="is damaged .*: rebuilding it") as caught:
        loaded = compile_function(function)
    assert len(caught) == 1
    assert loaded is not None and _evaluates_right(loaded, function)
    _load_quietly(function)  # rebuilt once: the next load is quiet


def test_an_unwritable_cache_is_said_once_and_the_library_still_works(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")  # even root cannot make a folder under a file
    monkeypatch.setenv("XDG_CACHE_HOME", str(blocker))
    function = _function()
    with pytest.warns(CompiledCacheWarning, match="cannot write the compiled-code cache"):
        library = compile_function(function)
    assert library is not None and _evaluates_right(library, function)


def test_the_note_of_a_build_for_an_unwritable_cache_does_not_say_cached(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """Before: "(once per machine, cached in <the folder it could not write>)"."""
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("XDG_CACHE_HOME", str(blocker))
    function = _function()
    with pytest.warns(CompiledCacheWarning):
        compiled_library("cosim_note_test", [function], note="compiling a test function")
    note = capsys.readouterr().err.strip()
    assert note.startswith("cosim: note: compiling a test function (for this run only: ")
    assert "cannot be written" in note and "cached in" not in note
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    compiled_library("cosim_note_test", [function], note="compiling a test function")
    assert f"(once per machine, cached in {tmp_path / 'cache'}" in capsys.readouterr().err


def test_an_unwritable_cache_builds_a_library_once_per_process(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """Before: every user of the library in the process built it again, each with its note
    and warning (the plant's physics step twice a run)."""
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("XDG_CACHE_HOME", str(blocker))
    function = _function()
    with pytest.warns(CompiledCacheWarning):
        first = compiled_library("cosim_once_test", [function], note="compiling it")
    assert "compiling it" in capsys.readouterr().err
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no second warning
        second = compiled_library("cosim_once_test", [function], note="compiling it")
    assert second == first and capsys.readouterr().err == ""
    assert first is not None and str(os.getpid()) in str(first)


def test_an_unwritable_cache_is_said_once_for_every_library_it_cannot_take(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Before: once per library, three times a run: each warning's place was forgotten
    when a block that catches warnings (the run's) ended."""
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("XDG_CACHE_HOME", str(blocker))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")  # every warning issued is recorded
        for name in ("cosim_first_test", "cosim_second_test"):
            with warnings.catch_warnings():  # as a run's own block does
                compiled_library(name, [_function(f"{name}_probe")])
    said = [w for w in caught if issubclass(w.category, CompiledCacheWarning)]
    assert len(said) == 1, [str(w.message) for w in said]


@pytest.mark.slow
def test_a_truncated_tyre_library_no_longer_kills_every_run(tmp_path: Path) -> None:
    """The SIGBUS of a half-written library mapped into the plant: now a note and a rebuild."""
    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path / "cache"),
           "MUJOCO_GL": os.environ.get("MUJOCO_GL", "disable")}

    def run(name: str) -> subprocess.CompletedProcess[str]:
        # The NLP and the filter in CasADi's virtual machine: the empty cache then builds
        # only the plant's libraries, the ones this test is about (not 40 s of others).
        return subprocess.run([COSIM, "run", "lane-change", "--duration", "0.1", "--set",
                               "tracker.compiled=false", "--set", "estimator.compiled=false",
                               "--out", str(tmp_path / name)], env=env, capture_output=True,
                              text=True, timeout=300, check=False)

    assert run("first.mcap").returncode == 0
    (library,) = (tmp_path / "cache").rglob("cosim_tyre_patches.so")
    library.write_bytes(library.read_bytes()[:4096])
    damaged = run("second.mcap")
    assert damaged.returncode == 0, damaged.stderr
    (line,) = damaged.stderr.strip().splitlines()
    assert "is damaged (the library has 4096 bytes" in line
    again = run("third.mcap")
    assert again.returncode == 0 and again.stderr == ""


@pytest.mark.parametrize("manifest", ['{"size": Infinity, "sha256": "x"}',
                                      "[" * 100_000 + "]" * 100_000])
def test_a_hand_edited_manifest_is_damage_not_a_traceback(cache: Path, manifest: str) -> None:
    """Before: OverflowError (size Infinity) and RecursionError (deep nesting)."""
    function = _function("cache_manifest")
    assert _load_quietly(function) is not None
    (entry,) = cache.iterdir()
    (entry / MANIFEST).write_text(manifest)
    with pytest.warns(CompiledCacheWarning, match="is damaged .*missing or unreadable"):
        library = compile_function(function)
    assert library is not None and _evaluates_right(library, function)


def test_the_cache_keeps_within_its_bound_least_recently_used_first(
        cache: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Before: every friction, mass or belief a sweep tried left a library for good (171
    entries here)."""
    from cosim.core.compiled_cache import entries

    first, second, third = (_function(f"cache_lru_{i}") for i in range(3))
    for function in (first, second):
        assert _load_quietly(function) is not None
    size = max(e.size_bytes for e in entries())
    old = next(e.path for e in entries() if e.name == "cache_lru_0")
    os.utime(old / MANIFEST, (1e9, 1e9))  # used long ago
    assert _load_quietly(second) is not None  # a use marks the entry
    monkeypatch.setenv("COSIM_CACHE_MAX_MB", str(2.5 * size / 1e6))
    assert _load_quietly(third) is not None  # three do not fit: the oldest goes
    assert sorted(e.name for e in entries()) == ["cache_lru_1", "cache_lru_2"]


def test_cosim_cache_shows_and_clears(cache: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from cosim.cli import main

    assert _load_quietly(_function("cache_shown")) is not None
    assert main(["cache"]) == 0
    out = capsys.readouterr().out
    assert f"{cache}: 1 entries" in out and "cache_shown" in out
    assert main(["cache", "--clear"]) == 0
    assert "removed 1 entries" in capsys.readouterr().out
    assert not any(cache.iterdir())


def test_two_processes_needing_one_library_build_it_once(tmp_path: Path) -> None:
    """Before: each of a sweep's workers on an empty cache compiled the same library (the
    EKF's 20 s twice on two workers); now the second waits for the first and loads it."""
    script = ("import casadi as ca\n"
              "from cosim.core.compiled_function import compiled_library\n"
              "x = ca.SX.sym('x', 2)\n"
              "f = ca.Function('cache_race', [x], [x[0] * x[1]])\n"
              "assert compiled_library('cache_race', [f], key=f.serialize(),"
              " note='building cache_race') is not None\n")
    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path)}
    processes = [subprocess.Popen([sys.executable, "-c", script], env=env,
                                  stderr=subprocess.PIPE, text=True) for _ in range(3)]
    errs = [p.communicate(timeout=300)[1] for p in processes]
    assert all(p.returncode == 0 for p in processes), errs
    assert sum(err.count("cosim: note: building cache_race") for err in errs) == 1, errs
    assert [p.name for p in (tmp_path / "cosim").iterdir()] == [
        next((tmp_path / "cosim").iterdir()).name]  # one entry, no lock left
