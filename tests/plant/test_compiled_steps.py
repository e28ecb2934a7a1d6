"""The plant's physics steps as one compiled C call: the Python step's numbers, bit for bit,
the runner's jumps between due instants give the per-step loop's run, and a new process
finds the tyres' and the steps' libraries by their recipe without building the tyres'
graph."""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import cosim
import cosim.plant.car
from cosim.core.compiled_function import CompiledCacheWarning, CompileFailedWarning
from cosim.core.initial_state import InitialState
from cosim.core.records import ActuatorCommand
from cosim.core.vehicle_params import PlantConfig
from cosim.plant.car import MujocoPlant
from cosim.simulation.metric_keys import WALL_CLOCK_KEYS

DT_S = 0.002


def _pair(config: PlantConfig) -> tuple[MujocoPlant, MujocoPlant]:
    compiled = MujocoPlant(config, DT_S, InitialState(speed_mps=15.0))
    python = MujocoPlant(config, DT_S, InitialState(speed_mps=15.0))
    python._steps = None  # the reference: the actuators and tyres in Python
    python._read_state = None  # and its state read in Python
    assert compiled._steps is not None
    return compiled, python


def _command(k: int) -> ActuatorCommand:
    """Steering swings, drive on and off (the power limit acts), a brake now and then."""
    return ActuatorCommand(t_s=k * DT_S, steer_rad=float(0.08 * np.sin(k / 150.0)),
                           drive_torque_nm=3000.0 if k % 700 < 350 else 0.0,
                           brake_torque_nm=2500.0 if k % 900 > 780 else 0.0)


def _drive_in_chunks(plants: tuple[MujocoPlant, ...], steps: int,
                    check: bool = False) -> None:
    """``steps`` physics steps of :func:`_command` (a new command every 10 steps), in
    chunks of 1 to 7 steps as the runner takes them; ``check``: the plants the same after
    each chunk."""
    k = 0
    while k < steps:
        for plant in plants:
            if k % 10 == 0:
                plant.apply(_command(k))
            plant.advance_steps(1 + k % 7)
        k += 1 + k % 7
        if check:
            assert _same(*plants), f"apart after step {k}"


def _same(a: MujocoPlant, b: MujocoPlant) -> bool:
    return all(np.array_equal(getattr(a.data, name), getattr(b.data, name))
               for name in ("qpos", "qvel", "ctrl", "xfrc_applied", "efc_force"))


@pytest.mark.parametrize(("drive", "friction"), [("rwd", 1.0), ("awd", 1.0), ("rwd", 0.55)])
def test_the_compiled_steps_are_the_python_steps_bit_for_bit(drive: str,
                                                             friction: float) -> None:
    # 3,000 steps (6 s) of swinging steering, drive with the power limit and brakes, in
    # chunks of 1 to 7 steps as the runner takes them: every array MuJoCo integrates and
    # every state the plant reports is the Python step's to the last bit (on a slippery
    # road too: the friction is the compiled tyres' input, not a number built into them).
    compiled, python = _pair(dataclasses.replace(PlantConfig(), drive=drive,
                                                 tyre_friction=friction))
    _drive_in_chunks((compiled, python), 3000, check=True)
    assert compiled.state() == python.state()
    assert compiled.tyre_forces() == python.tyre_forces()
    assert abs(compiled.state().y_m) > 1.0  # it turned


def test_the_state_read_in_c_is_the_pythons_bit_for_bit() -> None:
    # After every chunk of 3,000 steps of steering, drive and brakes (rolling, pitching,
    # the wheels spinning up and locking): VehicleState from C equals the Python one.
    plant, _ = _pair(dataclasses.replace(PlantConfig(), drive="awd"))
    k, states = 0, 0
    while k < 3000:
        if k % 10 == 0:
            plant.apply(_command(k))
        plant.advance_steps(1 + k % 7)
        k += 1 + k % 7
        assert plant.state() == plant.state_in_python(), f"apart after step {k}"
        states += 1
    assert states > 500 and abs(plant.state().roll_rad) > 1e-3


@pytest.mark.parametrize(("drive", "mass_kg", "friction"),
                         [("rwd", 1500.0, 1.0), ("awd", 1320.5, 0.6)])
def test_the_car_settles_in_c_as_in_python(drive: str, mass_kg: float, friction: float,
                                           monkeypatch: pytest.MonkeyPatch) -> None:
    # The static equilibrium every run starts from: 750 steps of MuJoCo and the tyres, in
    # one C call and in Python, to the bit (height, roll, pitch, suspension, radii, loads);
    # and after 20 steps, still bouncing on tyres that started unloaded.
    config = dataclasses.replace(PlantConfig(), drive=drive, mass_kg=mass_kg,
                                 tyre_friction=friction)
    plant = MujocoPlant(config, DT_S, InitialState(), settle_here=True)
    steps = plant._steps
    for duration_s in (None, 20 * DT_S):
        if duration_s is not None:
            monkeypatch.setattr(cosim.plant.car, "SETTLE_DURATION_S", duration_s)
        plant._steps = steps
        in_c = plant._settle()
        plant._steps = None
        in_python = plant._settle()
        assert in_c == in_python
    assert in_c != plant.equilibrium  # 20 steps are not yet at rest
    assert plant.equilibrium.static_load_n[0] > 2000.0


def test_a_run_jumping_between_due_steps_is_the_per_step_run(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # The runner advances the plant from one due step to the next in one call; with the
    # Python plant stepping one step at a time the run's metrics are the same numbers.
    config = cosim.load_config("lane-change", duration_s=4.0, seed=11)
    jumped = cosim.run(config, tmp_path / "jumped.mcap").metrics
    monkeypatch.setattr(MujocoPlant, "_compiled_steps", lambda self: None)
    calls: list[int] = []
    original = MujocoPlant.advance_steps

    def one_at_a_time(self: MujocoPlant, n: int) -> None:
        calls.append(n)
        for _ in range(n):
            original(self, 1)

    monkeypatch.setattr(MujocoPlant, "advance_steps", one_at_a_time)
    stepped = cosim.run(config, tmp_path / "stepped.mcap").metrics
    assert max(calls) > 1  # the loop did jump
    timing = WALL_CLOCK_KEYS
    assert {k: v for k, v in jumped.items() if "_ms_" not in k and k not in timing} == \
        {k: v for k, v in stepped.items() if "_ms_" not in k and k not in timing}


def test_without_a_c_compiler_the_python_step_runs_with_one_warning(
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("CC", "no-such-compiler")
    with pytest.warns(CompiledCacheWarning, match="the plant's tyres and physics step run "
                      "in Python") as caught:
        plant = MujocoPlant(PlantConfig(), DT_S, InitialState(speed_mps=15.0))
    assert len(caught) == 1 and plant._steps is None
    plant.apply(_command(0))
    plant.advance_steps(50)
    assert plant.state().vx_mps > 14.0


def test_one_library_serves_every_road() -> None:
    """The friction is a parameter of the compiled step: a second road builds nothing."""
    dry = MujocoPlant(PlantConfig(), DT_S, InitialState(speed_mps=15.0))
    wet = MujocoPlant(dataclasses.replace(PlantConfig(), tyre_friction=0.37), DT_S,
                      InitialState(speed_mps=15.0))
    assert dry._steps is not None and wet._steps is not None
    assert dry._steps._library._name == wet._steps._library._name


def test_a_physics_step_that_does_not_compile_says_why_in_one_line(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Before: the run fell back to the Python step, about 2x slower, with nothing said and
    gcc's error dropped."""
    from cosim.plant import compiled_steps

    broken = tmp_path / "plant_step.c"
    broken.write_text(compiled_steps.SOURCE.read_text().replace(
        "#include", "this is not C;\n#include", 1))
    monkeypatch.setattr(compiled_steps, "SOURCE", broken)
    with pytest.warns(CompileFailedWarning) as caught:
        plant = MujocoPlant(PlantConfig(), DT_S, InitialState(speed_mps=15.0))
    assert len(caught) == 1, [str(w.message) for w in caught]
    line = str(caught[0].message)
    assert line.startswith("cannot compile cosim_plant_steps (") and "error" in line, line
    assert line.endswith("the plant's physics step runs step by step in Python, about 2x "
                         "slower")
    assert plant._steps is None
    plant.apply(_command(0))
    plant.advance_steps(50)
    assert plant.state().vx_mps > 14.0


def test_cc_with_arguments_compiles(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``CC='gcc -O0'`` was looked up as one program name and found no compiler."""
    import casadi as ca

    from cosim.core.compiled_function import compiled_library, compiler

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.setenv("CC", "gcc -O0")
    assert compiler() is not None and compiler()[1:] == ["-O0"]
    x = ca.SX.sym("x")
    library = compiled_library("cc_args_square", [ca.Function("cc_args_square", [x], [x * x])])
    assert library is not None and library.is_file()


def test_one_library_serves_every_tyre_and_road() -> None:
    """A sweep over tyres and roads compiles nothing new: the tyres' numbers and the road's
    friction are inputs of the compiled step, not constants of its code. Another tyre on
    another road follows the plain reference (:func:`cosim.plant.tyre_model.patch_step`
    per wheel, in Python: its numbers reach the C code) and not the default tyre."""
    from cosim.core.tyre_params import TyreParams

    tyre = dataclasses.replace(TyreParams(), lateral_shape=1.3,
                               cornering_stiffness_max_prad=11.0, nominal_load_n=4500.0)
    other = dataclasses.replace(PlantConfig(), tyre=tyre, tyre_friction=0.8)
    start = InitialState(speed_mps=15.0)
    compiled = MujocoPlant(other, DT_S, start)
    reference = MujocoPlant(other, DT_S, start, one_call_tyres=False)
    default = MujocoPlant(PlantConfig(), DT_S, start)
    assert compiled._steps is not None and default._steps is not None
    assert compiled._steps._library._name == default._steps._library._name
    for k in range(0, 1000, 5):
        for plant in (compiled, reference, default):
            plant.apply(_command(k))
            plant.advance_steps(5)
    np.testing.assert_allclose(compiled.data.qvel, reference.data.qvel, rtol=1e-6,
                               atol=1e-9)
    assert np.max(np.abs(compiled.data.qvel - default.data.qvel)) > 1e-3


def test_traffic_runs_on_the_compiled_steps_bit_for_bit() -> None:
    """The cars' mocap poses after each step are set by the C step from poses Python
    computes for the steps between due instants: the Python step's numbers, bit for bit,
    while a car cuts in beside the ego."""
    from cosim.simulation.scenario_config import load_config
    from cosim.simulation.traffic_loop import build_traffic

    config = load_config("acc-cut-in")
    start = InitialState(speed_mps=20.0)
    compiled = MujocoPlant(config.plant, DT_S, start, traffic=build_traffic(config))
    python = MujocoPlant(config.plant, DT_S, start, traffic=build_traffic(config))
    python._steps = None
    assert compiled._steps is not None
    placed = compiled.data.mocap_pos.copy()
    _drive_in_chunks((compiled, python), 6000)  # 12 s: the cut-in starts at 8 s
    assert _same(compiled, python)
    assert np.array_equal(compiled.data.mocap_pos, python.data.mocap_pos)
    assert np.array_equal(compiled.data.mocap_quat, python.data.mocap_quat)
    moved = compiled.data.mocap_pos - placed
    assert np.all(moved[:, 0] > 100.0) and np.ptp(moved[:, 1]) > 1.0  # one changed lanes


def test_a_new_process_takes_the_tyres_from_their_library_without_their_graph() -> None:
    """Once a process has found the tyres' and the physics step's libraries (kept for the
    tyres' recipe, :func:`cosim.core.compiled_function.function_by_recipe`), the next one
    builds neither the four-tyre graph nor its serialisation, and its car drives the same
    second to the bit (each float's repr)."""
    script = """
import sys
from cosim.core.initial_state import InitialState
from cosim.core.records import ActuatorCommand
from cosim.core.vehicle_params import PlantConfig
from cosim.plant import tyre_forces
from cosim.plant.car import MujocoPlant
built = []
real = tyre_forces.tyre_patches_function
tyre_forces.tyre_patches_function = lambda *args: built.append(args) or real(*args)
plant = MujocoPlant(PlantConfig(), 0.002, InitialState(speed_mps=15.0))
assert plant._steps is not None
plant.apply(ActuatorCommand(t_s=0.0, steer_rad=0.05, drive_torque_nm=2000.0,
                            brake_torque_nm=0.0))
plant.advance_steps(500)
print(len(built), repr(plant.state()))
"""
    env = {**os.environ, "MUJOCO_GL": "disable"}
    first, second = (subprocess.run([sys.executable, "-c", script], env=env, check=True,
                                    capture_output=True, text=True).stdout.split(" ", 1)
                     for _ in range(2))
    assert second[0] == "0"  # found by the recipe the first process kept (or found)
    assert first[1] == second[1]
