"""Compiled libraries that link a Python package's shared library (MuJoCo's, CasADi's
hpipm) are keyed without the package's folder, and load wherever they were built
(:func:`cosim.core.compiled_function.compiled_library`'s ``relocatable``)."""

from __future__ import annotations

import ctypes
import subprocess
import sys
from pathlib import Path

import casadi as ca
import mujoco
import pytest

from cosim.core.compiled_function import compiled_library, compiler, relocated
from tracker.mpc.compiled_rti import casadi_folder, load_hpipm

pytestmark = pytest.mark.skipif(compiler() is None, reason="no C compiler")


def test_a_relocatable_folder_is_not_part_of_the_key(tmp_path: Path,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    # Two virtualenvs' folders of one dependency: one cache entry; named in the flags
    # without being relocatable, another.
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    x = ca.SX.sym("x")
    twice = ca.Function("twice_probe", [x], [2.0 * x])
    here, there = tmp_path / "venv-a" / "pkg", tmp_path / "venv-b" / "pkg"
    first = compiled_library("twice_probe", [twice], (f"-I{here}",), key="probe",
                             relocatable=(here,))
    second = compiled_library("twice_probe", [twice], (f"-I{there}",), key="probe",
                              relocatable=(there,))
    fixed = compiled_library("twice_probe", [twice], (f"-I{there}",), key="probe")
    assert first is not None and second == first
    assert fixed is not None and fixed != first
    assert relocated((f"-I{here}/include", f"-Wl,-rpath,{here}"), (here,)) == (
        "-I<dependency 0>/include", "-Wl,-rpath,<dependency 0>")


def _build(tmp_path: Path, source: str, flags: list[str]) -> Path:
    """A shared library of ``source`` whose run path names a folder that does not exist
    (the virtualenv that built it, deleted since)."""
    assert compiler() is not None
    c_file, library = tmp_path / "probe.c", tmp_path / "probe.so"
    c_file.write_text(source)
    subprocess.run([*compiler(), "-shared", "-fPIC", str(c_file), "-o", str(library), *flags,
                    f"-Wl,-rpath,{tmp_path / 'deleted-venv'}"], check=True)
    return library


def _loads_alone(library: Path) -> bool:
    """Whether a fresh interpreter that loaded nothing before loads ``library``."""
    return subprocess.run([sys.executable, "-c", f"import ctypes; ctypes.CDLL({str(library)!r})"],
                          capture_output=True).returncode == 0


MUJOCO_HEADER = Path(mujoco.__file__).parent / "include" / "mujoco" / "mujoco.h"


@pytest.mark.skipif(not MUJOCO_HEADER.is_file(),
                    reason="a mujoco build without its headers (the physics step is not compiled)")
def test_the_plant_steps_find_the_mujoco_that_import_mujoco_loaded(tmp_path: Path) -> None:
    folder = Path(mujoco.__file__).parent
    name = sorted(folder.glob("libmujoco.so*"))[-1].name
    library = _build(tmp_path, "#include <mujoco/mujoco.h>\n"
                               "int probe(void) { return mj_version(); }\n",
                     [f"-I{folder / 'include'}", f"-L{folder}", f"-l:{name}"])
    assert not _loads_alone(library)  # its run path leads nowhere
    assert ctypes.CDLL(str(library)).probe() == mujoco.mj_version()


@pytest.mark.skipif(not (casadi_folder() / "libhpipm.so").is_file(),
                    reason="a CasADi without hpipm (the real-time iteration is not compiled)")
def test_the_real_time_iteration_finds_the_hpipm_load_hpipm_loaded(tmp_path: Path) -> None:
    folder = casadi_folder()
    library = _build(tmp_path, "extern int d_ocp_qp_dim_memsize(int);\n"
                               "int probe(void) { return d_ocp_qp_dim_memsize(5) > 0; }\n",
                     [f"-L{folder}", "-lhpipm"])
    assert not _loads_alone(library)
    load_hpipm()
    assert ctypes.CDLL(str(library)).probe() == 1
