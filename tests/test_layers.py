"""The import layering of docs/architecture.md holds: no package imports a part above it.

Every ``import`` statement of every module (at the top, inside functions, under
``TYPE_CHECKING``) is read with :mod:`ast`; a module may import its own part, or a part on a
strictly lower layer. So a controller or a filter never imports the plant, the sensors or the
run, and the plant knows no controller.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

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
}
"""Layer of each part; the modules at the base of ``cosim/`` are layer 0."""

LAZY_FACADE = ("cosim", "cosim.api")
"""The one upward import allowed: the package ``cosim`` resolves ``cosim.run`` and the other
API names from :mod:`cosim.api` on first use (module ``__getattr__``), never at import."""


def part_of(module: str) -> str:
    """The part (key of :data:`LAYERS`) a dotted module name belongs to, or ``"cosim"``."""
    for part in sorted(LAYERS, key=len, reverse=True):
        if module == part or module.startswith(part + "."):
            return part
    return "cosim"


def layer_of(part: str) -> int:
    return LAYERS.get(part, 0)


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
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
            if name.split(".")[0] in ("cosim", "tracker", "estimation"):
                found.append((node.lineno, name))
    return found


SOURCES = sorted(
    path
    for package in ("cosim", "tracker", "estimation")
    for path in (ROOT / package).rglob("*.py")
)


def test_every_part_has_a_layer() -> None:
    parts = {part_of(module_name(path)) for path in SOURCES}
    assert parts <= set(LAYERS) | {"cosim"}
    assert len(SOURCES) > 50


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: str(p.relative_to(ROOT)))
def test_imports_point_down(path: Path) -> None:
    importer = part_of(module_name(path))
    upward = []
    for line, name in imported_modules(path):
        imported = part_of(name)
        if imported == importer or name in ("cosim.__version__",):
            continue
        if (module_name(path), part_of(name)) == LAZY_FACADE:
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
    assert layer_of(part_of(name)) >= layer_of(part_of("tracker.ltv_mpc"))
