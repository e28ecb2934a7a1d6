"""A pure builder's result kept on disk (cosim.core.built_on_disk): read back only for the
same arguments and the same files, rebuilt when damaged, never in the way when the cache
cannot be written; the sedan's MJCF text read back is the text PyMJCF writes."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from cosim.core.built_on_disk import code_stamp, kept_on_disk
from cosim.core.compiled_cache import entries


class Builder:
    """A builder that counts its calls."""

    def __init__(self, value: object) -> None:
        self.value, self.calls = value, 0

    def __call__(self) -> object:
        self.calls += 1
        return self.value


@pytest.fixture
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    return tmp_path / "cache" / "cosim"


@pytest.fixture
def data(tmp_path: Path) -> Path:
    """A folder of data files the builder reads (as the models folder is)."""
    folder = tmp_path / "data"
    folder.mkdir()
    (folder / "car.xml").write_text("<mujoco/>")
    return folder


def test_the_same_arguments_and_files_read_back_what_was_built(cache: Path,
                                                               data: Path) -> None:
    value = {"xml": "<mujoco model='a'/>", "assets": {}, "numbers": [0.1, 1e-300]}
    first = Builder(value)
    assert kept_on_disk("thing", "args(1)", first, folders=(data,)) == value
    again = Builder({"other": True})
    assert kept_on_disk("thing", "args(1)", again, folders=(data,)) == value
    assert (first.calls, again.calls) == (1, 0)
    assert [e.name for e in entries(cache)] == ["thing"]


def test_other_arguments_or_an_edited_file_build_afresh(cache: Path, data: Path) -> None:
    kept_on_disk("thing", "args(1)", Builder("one"), folders=(data,))
    assert kept_on_disk("thing", "args(2)", Builder("two"), folders=(data,)) == "two"
    before = code_stamp((), (str(data),))
    (data / "car.xml").write_text("<mujoco model='edited'/>")  # another size
    code_stamp.cache_clear()  # a new process
    assert code_stamp((), (str(data),)) != before
    assert kept_on_disk("thing", "args(1)", Builder("three"), folders=(data,)) == "three"
    stamp = code_stamp((), (str(data),))
    os.utime(data / "car.xml", ns=(1, 1))  # the same size, another modification time
    code_stamp.cache_clear()
    assert code_stamp((), (str(data),)) != stamp


def test_a_damaged_entry_is_built_again_and_replaced(cache: Path, data: Path) -> None:
    kept_on_disk("thing", "args(1)", Builder([1, 2, 3]), folders=(data,))
    (entry,) = cache.iterdir()
    (entry / "thing.json").write_text("[1, 2, 4]")  # the same size, another content
    rebuilt = Builder([1, 2, 3])
    assert kept_on_disk("thing", "args(1)", rebuilt, folders=(data,)) == [1, 2, 3]
    (entry / "manifest.json").write_text('{"size": Infinity, "sha256": "x"}')
    assert kept_on_disk("thing", "args(1)", rebuilt, folders=(data,)) == [1, 2, 3]
    assert rebuilt.calls == 2
    assert json.loads((entry / "thing.json").read_text()) == [1, 2, 3]


def test_an_unwritable_cache_builds_every_time(tmp_path: Path, data: Path,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("XDG_CACHE_HOME", str(blocker))
    builder = Builder("value")
    for _ in range(2):
        assert kept_on_disk("thing", "args(1)", builder, folders=(data,)) == "value"
    assert builder.calls == 2


def test_the_sedan_read_back_is_pymjcfs_text_and_needs_no_pymjcf(tmp_path: Path) -> None:
    """A process that finds the sedan's text in the cache builds the same MuJoCo model
    without importing PyMJCF; the text is the one PyMJCF writes."""
    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path / "cache"), "MUJOCO_GL": "disable"}
    script = """
import sys
from cosim.plant.sedan_model import sedan_xml_and_assets
from cosim.simulation.scenario_config import load_config
config = load_config("lane-change")
xml, assets = sedan_xml_and_assets(config.plant, config.sim.physics_dt_s)
print(len(xml), "dm_control.mjcf" in sys.modules)
if sys.argv[1] == "check":
    from cosim.plant.sedan_model import build_sedan
    root = build_sedan(config.plant, config.sim.physics_dt_s)
    assert xml == root.to_xml_string(precision=12) and assets == root.get_assets()
"""
    outputs = [subprocess.run([sys.executable, "-c", script, mode], env=env, check=True,
                              capture_output=True, text=True).stdout.split()
               for mode in ("build", "read", "check")]
    assert outputs[0][1] == "True"  # built with PyMJCF and written
    assert outputs[1][1] == "False"  # read back: PyMJCF not imported
    assert outputs[0][0] == outputs[1][0] == outputs[2][0]


def test_a_recipe_finds_the_library_in_a_new_process_without_serialising(
        cache: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``load_library(..., recipe=...)``: the first process serialises the functions for
    the key and keeps the entry's hash for the recipe; the next one (the process's own
    caches emptied) loads the same library without serialising; another recipe does."""
    import casadi as ca

    import cosim.core.compiled_function as compiled

    x = ca.SX.sym("x", 2)
    function = ca.Function("recipe_probe", [x], [x[0] * x[1] + 3.0])
    calls: list[str] = []
    real = compiled.serialized.__wrapped__

    def counted(f: ca.Function) -> str:
        calls.append(f.name())
        return real(f)

    def new_process() -> None:
        for cached in (compiled._functions_key, compiled._keyed_digest):
            cached.cache_clear()
        code_stamp.cache_clear()

    monkeypatch.setattr(compiled, "serialized", counted)
    assert compiled.load_library("recipe_probe", [function], recipe="probe(1)") is not None
    assert calls == ["recipe_probe"]
    library = next(e.path for e in entries(cache) if e.name == "recipe_probe")
    new_process()
    loaded = compiled.load_library("recipe_probe", [function], recipe="probe(1)")
    assert loaded is not None and loaded._name == str(library / "recipe_probe.so")
    assert calls == ["recipe_probe"]
    new_process()
    assert compiled.load_library("recipe_probe", [function], recipe="probe(2)") is not None
    assert calls == ["recipe_probe", "recipe_probe"]
    assert sorted(e.name for e in entries(cache)) == ["recipe_probe", "recipe_probe_key",
                                                      "recipe_probe_key"]


def test_an_entry_of_another_form_is_built_again(cache: Path, data: Path) -> None:
    """An entry written by hand with a manifest that fits it, but not of the builder's form
    (``valid``), is built again rather than handed to the caller."""
    from cosim.core.compiled_cache import file_digest

    def valid(value: object) -> bool:
        return isinstance(value, dict) and isinstance(value.get("xml"), str)

    kept_on_disk("thing", "args(1)", Builder({"xml": "<mujoco/>"}), folders=(data,),
                 valid=valid)
    (entry,) = cache.iterdir()
    (entry / "thing.json").write_text('{"xml": 3}')
    (entry / "manifest.json").write_text(json.dumps({
        "size": (entry / "thing.json").stat().st_size,
        "sha256": file_digest(entry / "thing.json")}))
    rebuilt = Builder({"xml": "<mujoco/>"})
    assert kept_on_disk("thing", "args(1)", rebuilt, folders=(data,),
                        valid=valid) == {"xml": "<mujoco/>"}
    assert rebuilt.calls == 1


def test_a_name_keeps_the_entries_used_last(cache: Path, data: Path,
                                            monkeypatch: pytest.MonkeyPatch) -> None:
    """A new entry replaces the one of its name used least recently beyond the limit;
    entries of other names are left alone."""
    import cosim.core.built_on_disk as kept

    monkeypatch.setattr(kept, "KEPT_PER_NAME", 3)
    kept_on_disk("other", "args(0)", Builder("other"), folders=(data,))
    for i in range(5):
        kept_on_disk("thing", f"args({i})", Builder(i), folders=(data,))
        for entry in cache.iterdir():  # each write later than the ones before
            if entry.name.startswith("thing-") and (entry / "thing.json").read_text() == str(i):
                os.utime(entry / "manifest.json", (1e9 + i, 1e9 + i))
    kept_on_disk("thing", "args(2)", Builder(2), folders=(data,))  # read: used now
    kept_on_disk("thing", "args(5)", Builder(5), folders=(data,))
    values = sorted(json.loads((e / "thing.json").read_text())
                    for e in cache.iterdir() if e.name.startswith("thing-"))
    assert values == [2, 4, 5]
    assert sum(e.name.startswith("other-") for e in cache.iterdir()) == 1
