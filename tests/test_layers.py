"""The import layering of docs/architecture.md holds: no package imports a part above it.

Every ``import`` statement of every module (at the top, inside functions, under
``TYPE_CHECKING``) is read with :mod:`ast`; a module may import its own part, or a part on a
strictly lower layer. So a controller or a filter never imports the plant, the sensors or
the run, and the plant knows no controller. Every sub-package must have a layer: one this
table does not know is a failure (a new part is placed on purpose, here and in the docs).
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

PACKAGES = ("cosim", "tracker", "estimation")
"""The project's Python packages."""

LAYERS: dict[str, int] = {
    "cosim.cli": 7,
    "cosim.api": 7,
    "cosim.sweeps": 6,
    "cosim.identification": 5,
    "cosim.gym": 5,
    "cosim.plots": 5,
    "cosim.simulation": 4,
    "cosim.plant": 3,
    "cosim.log": 3,
    "tracker": 2,
    "estimation": 2,
    "cosim.sensing": 1,
    "cosim.scenarios": 1,
    "cosim.cars": 1,
    "cosim.core": 0,
    "cosim": 8,
}
"""Layer of each part. ``cosim`` is the package's own ``__init__`` alone, the facade on top:
it resolves ``cosim.run`` and the other public names on first use (module ``__getattr__``),
so nothing below may import it (but ``cosim.__version__``); every other module belongs to
the longest part its dotted name starts with."""


def part_of(module: str) -> str | None:
    """The part (key of :data:`LAYERS`) a dotted module name belongs to; None if none."""
    if module == "cosim":
        return "cosim"
    for part in sorted(LAYERS, key=len, reverse=True):
        if part != "cosim" and (module == part or module.startswith(part + ".")):
            return part
    return None


def layer_of(part: str | None) -> int:
    if part is None:
        raise KeyError("a module outside every part has no layer")
    return LAYERS[part]


def module_name(path: Path, root: Path = ROOT) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def imported_modules(path: Path) -> list[tuple[int, str]]:
    """(line, dotted name) of every absolute import of this project's packages in ``path``."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            # ``from cosim import x`` may name a sub-module: count it as the sub-module.
            names = [f"{node.module}.{alias.name}" for alias in node.names]
        else:
            continue
        for name in names:
            if name.split(".")[0] in PACKAGES:
                found.append((node.lineno, name))
    return found


def sources(root: Path) -> list[Path]:
    return sorted(path for package in PACKAGES if (root / package).is_dir()
                  for path in (root / package).rglob("*.py"))


def unknown_parts(root: Path) -> list[str]:
    """The sub-packages (and top-level modules) under ``root`` that no layer names."""
    found = set()
    for path in sources(root):
        name = module_name(path, root)
        if part_of(name) is None:
            found.add(".".join(name.split(".")[:2]))
    return sorted(found)


SOURCES = sources(ROOT)


def test_every_part_has_a_layer() -> None:
    assert unknown_parts(ROOT) == []
    assert len(SOURCES) > 50


def test_a_sub_package_without_a_layer_is_found(tmp_path: Path) -> None:
    """The check is not vacuous: a planted ``cosim/newpart`` (and a stray top-level module)
    has no layer, and the every-part test would fail on it."""
    for planted in ("cosim/newpart/__init__.py", "cosim/newpart/thing.py", "cosim/stray.py",
                    "cosim/core/fine.py", "tracker/anything.py"):
        (tmp_path / planted).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / planted).write_text("")
    assert unknown_parts(tmp_path) == ["cosim.newpart", "cosim.stray"]


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: str(p.relative_to(ROOT)))
def test_imports_point_down(path: Path) -> None:
    importer = part_of(module_name(path))
    upward = []
    for line, name in imported_modules(path):
        imported = part_of(name)
        if imported == importer or name in ("cosim.__version__",):
            continue
        if layer_of(imported) >= layer_of(importer):
            upward.append(f"line {line}: {name} (layer {layer_of(imported)}) from "
                          f"{importer} (layer {layer_of(importer)})")
    assert not upward, "\n".join(upward)


def test_the_checker_sees_an_upward_import(tmp_path: Path) -> None:
    """The check is not vacuous: a tracker importing the plant is found."""
    bad = tmp_path / "bad.py"
    bad.write_text("from cosim.plant.car import MujocoPlant\n")
    (name,) = (n for _, n in imported_modules(bad))
    assert layer_of(part_of(name)) >= layer_of(part_of("tracker.mpc.ltv_mpc"))


def _documented_layers() -> dict[str, int]:
    """The layer diagram of docs/architecture.md: part -> layer (the top line is the
    highest), read from its fenced block after 'Layers, each importing'."""
    text = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    block = text.split("Layers, each importing", 1)[1].split("```", 2)[1]
    rows = [row for row in block.strip("\n").split("\n") if row.strip()]
    layers = {}
    for layer, row in enumerate(reversed(rows)):
        for name in re.findall(r"[a-z_]+(?:/)?", row):
            layers[name.rstrip("/")] = layer
    return layers


def test_docs_architecture_shows_these_layers() -> None:
    documented = _documented_layers()
    for part, layer in LAYERS.items():
        short = part.removeprefix("cosim.") if part.startswith("cosim.") else part
        if part == "cosim":
            continue  # the package's __init__: the facade, named in the text
        assert documented.get(short) == layer, (part, documented.get(short), layer)


def test_docs_architecture_names_every_sub_package() -> None:
    text = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    for package in PACKAGES:
        for sub in sorted(p for p in (ROOT / package).iterdir()
                          if p.is_dir() and (p / "__init__.py").is_file()):
            assert f"`{package}/{sub.name}/`" in text, f"{package}/{sub.name}/"


SUITES = ("conformance", "mismatch", "js")
"""Test folders that are suites, not mirrors of a package: the plant's physics conformance,
the tracker's mismatch envelope, the JavaScript reader."""

ROOT_TESTS = ("test_api.py", "test_layers.py", "test_packaging.py", "test_test_order.py")
"""Tests of the whole: the public API, this layering, the distribution, the suite's order."""


def misplaced_tests(tests: Path, root: Path = ROOT) -> list[str]:
    """Test modules whose folder mirrors no package of the tree (``tests/<cosim part>/``,
    ``tests/tracker/<tracker part>/``, ``tests/estimation/``) and is no suite."""
    def packages(base: Path) -> set[str]:
        return {p.name for p in base.iterdir() if (p / "__init__.py").is_file()}

    cosim_parts, tracker_parts = packages(root / "cosim"), packages(root / "tracker")
    misplaced = []
    for path in sorted(tests.rglob("test_*.py")):
        parts = path.relative_to(tests).parts
        if "node_modules" in parts:
            continue
        if len(parts) == 1:
            ok = parts[0] in ROOT_TESTS
        elif parts[0] == "tracker":
            ok = len(parts) == 2 or parts[1] in tracker_parts
        else:
            ok = parts[0] in cosim_parts | {"estimation", *SUITES}
        if not ok:
            misplaced.append(str(path.relative_to(tests)))
    return misplaced


def test_tests_mirror_the_package_tree() -> None:
    assert misplaced_tests(ROOT / "tests") == []


def test_a_misplaced_test_is_found(tmp_path: Path) -> None:
    for planted in ("cosim/plant/__init__.py", "tracker/mpc/__init__.py",
                    "tests/test_stray.py", "tests/plant/test_ok.py", "tests/nowhere/test_x.py",
                    "tests/tracker/mpc/test_ok.py", "tests/tracker/gone/test_y.py"):
        (tmp_path / planted).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / planted).write_text("")
    assert misplaced_tests(tmp_path / "tests", tmp_path) == [
        "nowhere/test_x.py", "test_stray.py", "tracker/gone/test_y.py"]
