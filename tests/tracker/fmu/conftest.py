"""The example FMUs (examples/fmu), built once per session by examples/fmu/build.py."""

from __future__ import annotations

import importlib.util
import shutil
from pathlib import Path
from types import ModuleType

import pytest

BUILD_SCRIPT = Path(__file__).resolve().parents[3] / "examples" / "fmu" / "build.py"


def example_builder() -> ModuleType:
    """examples/fmu/build.py as a module (an example script, not a package: loaded from its
    file, as a user would run it)."""
    spec = importlib.util.spec_from_file_location("example_fmu_build", BUILD_SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="session")
def fmu_builder() -> ModuleType:
    return example_builder()


@pytest.fixture(scope="session")
def c_fmus(tmp_path_factory: pytest.TempPathFactory, fmu_builder: ModuleType) -> dict[int, Path]:
    """The Stanley C FMU for FMI 2 and FMI 3, by FMI version."""
    if shutil.which("gcc") is None:
        pytest.skip("no gcc: the C FMU cannot be compiled")
    out = tmp_path_factory.mktemp("c-fmus")
    return {version: fmu_builder.build_c_fmu(out, version) for version in (2, 3)}


@pytest.fixture(scope="session")
def python_fmus(tmp_path_factory: pytest.TempPathFactory,
                fmu_builder: ModuleType) -> dict[int, Path]:
    """The pure-pursuit Python FMU (pythonfmu, pythonfmu3) for FMI 2 and FMI 3."""
    out = tmp_path_factory.mktemp("python-fmus")
    return {version: fmu_builder.build_python_fmu(out, version) for version in (2, 3)}
