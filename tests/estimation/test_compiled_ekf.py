"""The EKF's models as compiled C (``estimator.compiled``): the same estimates as CasADi's
virtual machine, one library for every belief, and the virtual machine, with one warning,
when no C compiler works."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from cosim.core.compiled_function import CompiledCacheWarning
from cosim.core.initial_state import InitialState
from cosim.core.vehicle_params import VehicleParams
from estimation import joint_update, process_model
from estimation.config import EstimatorConfig
from estimation.registry import make_estimator
from tests.estimation.drive import Run, SensorSetup, lane_change, run_filter
from tests.machine_library import fresh_cache_with, libraries_built

SETUP = SensorSetup(gnss_sigma_m=0.5)
PROFILE = lane_change()


def _drive(config: EstimatorConfig) -> Run:
    return run_filter(PROFILE, setup=SETUP, config=config, seed=3)


def _largest_relative_difference(a: Run, b: Run) -> float:
    scale = np.maximum(np.abs(b.means), 1e-3)
    means = float(np.max(np.abs(a.means - b.means) / scale))
    covariances = float(np.max(np.abs(a.covariances - b.covariances)
                               / np.maximum(np.abs(b.covariances), 1e-12)))
    return max(means, covariances)


def _other_belief(config: EstimatorConfig) -> EstimatorConfig:
    """Process noise three times the default's and a slower lateral residual."""
    return dataclasses.replace(
        config, yaw_accel_psd_rad2ps3=3.0 * config.yaw_accel_psd_rad2ps3,
        lateral_residual_time_constant_s=2.0 * config.lateral_residual_time_constant_s)


@pytest.mark.slow  # the virtual machine's estimates (and the library, where not built yet)
def test_one_compiled_library_serves_every_belief_with_the_vms_estimates(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capfd: pytest.CaptureFixture[str]) -> None:
    # The whole lane change (IMU at 100 Hz, wheels, steering, 0.5 m GNSS): the compiled
    # models give the virtual machine's means and covariances to round-off, for the
    # default belief and for another one, from one library: the default's, built in the
    # machine's cache (with one note, where no test has built it yet), alone in a fresh
    # cache serves both beliefs without a build or a note (tests/machine_library.py). The
    # default without the front wheels' moment: the synthetic car of tests/estimation/drive.py
    # is a bicycle, and its filters leave the moment out (a structure, another library).
    default = EstimatorConfig(name="ekf", lateral_load_transfer=False)
    assert default.compiled
    with libraries_built() as built_libraries:
        make_estimator(default, InitialState(), VehicleParams())
    assert capfd.readouterr().err.count("cosim: note: compiling the EKF's models") <= 1
    (library,) = [p for p in built_libraries if p.parent.name.startswith("cosim_ekf-")]
    fresh_cache_with(library, monkeypatch, tmp_path)
    compiled = _drive(default)
    other = _other_belief(default)
    compiled_other = _drive(other)
    assert "note" not in capfd.readouterr().err
    # A filter whose recipe an earlier one kept takes the functions it compiles (the
    # sub-step, the cornering drag, the joint update) from the library (casadi.external)
    # without building their graphs: the same estimates, to the bit.
    built: list[str] = []
    for module, name in ((joint_update, "_joint_function"),
                         (process_model, "_process_functions")):
        real = getattr(module, name)
        monkeypatch.setattr(module, name, lambda *args, real=real, name=name:
                            built.append(name) or real(*args))
    again = _drive(default)
    assert built == []
    assert np.array_equal(again.means, compiled.means)
    assert np.array_equal(again.covariances, compiled.covariances)
    names = sorted(p.name.split("-")[0] for p in (tmp_path / "cosim").iterdir())
    # One library; the hash of its entry kept for each belief's recipe (built_on_disk).
    assert names == ["cosim_ekf", "cosim_ekf_key", "cosim_ekf_key"]
    vm = _drive(dataclasses.replace(default, compiled=False))
    vm_other = _drive(dataclasses.replace(other, compiled=False))
    assert _largest_relative_difference(compiled, vm) < 1e-9
    assert _largest_relative_difference(compiled_other, vm_other) < 1e-9
    # The other belief reached the compiled code: its estimates are not the default's.
    assert _largest_relative_difference(compiled_other, compiled) > 1e-3


def test_without_a_c_compiler_the_vm_estimates_with_one_warning(
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("CC", "no-such-compiler")
    with pytest.warns(CompiledCacheWarning, match="the EKF's models run in CasADi") as caught:
        run = _drive(EstimatorConfig(name="ekf"))
    assert len(caught) == 1
    quiet = _drive(EstimatorConfig(name="ekf", compiled=False))
    assert np.array_equal(run.means, quiet.means)


def test_the_filters_library_holds_its_sub_step_once(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # The covariance step calls the sub-step, which the library also exports: one C body
    # for both, with its repeated subexpressions shared (built so: process_model), where a
    # shared copy for the export and the graph as built for the call were two (the source
    # 3.2 MB and gcc 20 s, against 2.0 MB and 13 s).
    from cosim.core.compiled_function import _generate
    from estimation import compiled_models

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    handed: list[object] = []
    monkeypatch.setattr(compiled_models, "load_library",
                        lambda name, functions, **_: handed.extend(functions))
    monkeypatch.setattr(compiled_models, "compiler", lambda: "cc")  # no warning
    make_estimator(EstimatorConfig(name="ekf"), InitialState(), VehicleParams())
    _generate("ekf_probe", handed, str(tmp_path))
    source = (tmp_path / "ekf_probe.c").read_text()
    assert source.count("/* bicycle_covariance_step:(") == 1
    assert source.count("/* bicycle_step:(") == 1
