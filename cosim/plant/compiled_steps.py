"""The plant's physics steps as one compiled C call (``plant_step.c``).

:meth:`cosim.plant.car.MujocoPlant.advance` runs, per 2 ms physics step, the steering
actuator, the drive and brakes, the chassis's resistance, ``mj_step1``, the four tyres,
``mj_step2`` and its checks in Python around two MuJoCo calls: about 60 us a step of which
MuJoCo's own work is 8. ``plant_step.c`` does the same, expression by expression, in C
against MuJoCo's C API and the tyres' CasADi-generated C (:mod:`cosim.plant.tyre_patches`),
compiled together into one library (once per machine and model structure, cached as
:mod:`cosim.core.compiled_function` caches every library) and called through ctypes on
MuJoCo's own ``mjModel``/``mjData`` and numpy buffers: :meth:`CompiledSteps.advance` steps
the plant ``n`` times between the instants something is due (sensor, control, log), the
state that outlives a step kept in one numpy array (:data:`STATE_FIELDS`).

Used for the default plant (Magic Formula tyres), with traffic too (the cars' mocap
poses after each step are computed in Python for the ``n`` steps and set by the C step);
slip control keeps the Python step. MuJoCo's library is the one the
``mujoco`` package ships and has loaded already.
"""

from __future__ import annotations

import ctypes
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path

import casadi as ca
import mujoco
import numpy as np

from cosim.core.compiled_function import CompileFailedWarning, compiled_library, serialized

SOURCE = Path(__file__).with_name("plant_step.c")

STATE_FIELDS: tuple[str, ...] = (
    "command_rad", "angle_rad", "wheel_left_rad", "wheel_right_rad", "rate_left_radps",
    "rate_right_radps", "drive_cmd_nm", "brake_cmd_nm", "prev_vx_mps", "prev_vy_mps",
    "prev_vz_mps", "load0_n", "load1_n", "load2_n", "load3_n")
"""The state ``plant_step.c`` carries from step to step (its ``PS_*`` indices), in order."""
STATE = {name: i for i, name in enumerate(STATE_FIELDS)}

CONSTANT_FIELDS: tuple[str, ...] = (
    "dt_s", "decay", "step_max_rad", "max_steer_rad", "wheelbase_m", "front_track_m",
    "kv_over_kp", "inertia_over_kp", "max_drive_power_w", "min_power_spin_radps",
    "brake_spin_scale2", "brake_share0", "brake_share1", "brake_share2", "brake_share3",
    "drag_coefficient", "rolling_force_n", "rolling_speed_scale_mps", "max_velocity_norm2",
    "max_position_norm2", "tyre_friction")
"""The numbers of ``plant_step.c`` (its ``PC_*`` indices), in order: parameters of the
compiled library, so one library serves every car and road. The tyres' numbers follow the
last, the road's friction: from it on the array is the tyre function's ``road_tyres``
input (:func:`cosim.plant.tyre_patches.road_tyre_numbers`), so one library serves every
tyre too."""

INDEX_FIELDS: tuple[str, ...] = (
    "servo_left", "servo_right", "n_driven", "driven_dof0", "driven_dof1", "driven_dof2",
    "driven_dof3", "drive_act0", "drive_act1", "drive_act2", "drive_act3", "spin_dof0",
    "spin_dof1", "spin_dof2", "spin_dof3", "linvel_dof", "chassis_body", "wheel_body0",
    "wheel_body1", "wheel_body2", "wheel_body3", "tyre_geom0", "tyre_geom1", "tyre_geom2",
    "tyre_geom3")
"""The model addresses of ``plant_step.c`` (its ``PI_*`` indices), in order."""


def _mujoco_library() -> Path | None:
    """MuJoCo's shared library in the ``mujoco`` package, with its headers beside it."""
    folder = Path(mujoco.__file__).parent
    libraries = sorted(folder.glob("libmujoco.so*"))
    if not libraries or not (folder / "include" / "mujoco" / "mujoco.h").is_file():
        return None
    return libraries[-1]


STEPS_FALLBACK = "the plant's physics step runs step by step in Python, about 2x slower"
"""What the plant does without its compiled step (said in the one warning line)."""


def load_steps_library(tyres: ca.Function, graph: Callable[[], ca.Function],
                       recipe: str) -> ctypes.CDLL | None:
    """The library of ``plant_step.c`` and the tyre function ``tyres`` (whose graph
    ``graph()`` builds, from ``recipe``: :class:`cosim.plant.tyre_forces.MagicFormulaTyres`),
    compiled (on first use, with a note) or from the cache; None when there is no compiler,
    no MuJoCo headers (a ``mujoco`` build without them) or the library does not load. A new
    process finds it by the recipe, without building the graph
    (:func:`cosim.core.compiled_function.compiled_library`)."""
    library = _mujoco_library()
    if library is None:
        return None
    folder = library.parent
    flags = ("-O2", "-ffp-contract=off", f"-DPATCHES={tyres.name()}",
             f"-I{folder / 'include'}")
    link = (f"-L{folder}", f"-l:{library.name}", f"-Wl,-rpath,{folder}")
    # MuJoCo's folder is not part of the key (its version is): libmujoco is loaded by
    # ``import mujoco`` already, so a library built in another virtualenv finds it.
    built = compiled_library(
        "cosim_plant_steps", lambda: [graph()], flags,
        key=lambda: serialized(graph()) + mujoco.__version__, extra_sources=(SOURCE,),
        link_flags=link, note="compiling the plant's physics step to C (about 5 s)",
        fallback=STEPS_FALLBACK, relocatable=(folder,),
        recipe=f"{recipe}\nmujoco {mujoco.__version__}")
    if built is None:
        return None
    try:
        loaded = ctypes.CDLL(str(built))
        sizes = (ctypes.c_int * 3)()
        loaded.cosim_plant_sizes(sizes)
    except (OSError, AttributeError) as error:
        warnings.warn(f"cannot load the compiled physics step {str(built)!r} ({error}): "
                      f"{STEPS_FALLBACK}", CompileFailedWarning, stacklevel=2)
        return None
    if tuple(sizes) != (len(STATE_FIELDS), len(CONSTANT_FIELDS), len(INDEX_FIELDS)):
        warnings.warn(f"the compiled physics step {str(built)!r} has other sizes than "
                      f"plant_step.c's fields: {STEPS_FALLBACK}", CompileFailedWarning,
                      stacklevel=2)
        return None
    return loaded


class CompiledSteps:
    """``n`` physics steps of one plant in one C call, on its model and data."""

    def __init__(self, library: ctypes.CDLL, tyres: ca.Function, model: mujoco.MjModel,
                 data: mujoco.MjData, constants: dict[str, float], indices: dict[str, int],
                 buffers: Sequence[np.ndarray], road_tyres: np.ndarray,
                 mocap_slots: Sequence[int] = ()) -> None:
        """``road_tyres``: the tyre function's input of that name, whose first number is
        ``constants["tyre_friction"]``; ``mocap_slots``: the traffic cars' mocap slots, in
        the order of the poses :meth:`advance` is given."""
        self.state = np.zeros(len(STATE_FIELDS))
        """The state between steps (:data:`STATE_FIELDS`); written by the plant too."""
        if road_tyres[0] != constants["tyre_friction"]:
            raise ValueError("road_tyres must begin with the constants' tyre_friction")
        self._constants = np.concatenate((
            [constants[name] for name in CONSTANT_FIELDS], road_tyres[1:])).astype(float)
        self._indices = np.array([indices[name] for name in INDEX_FIELDS], dtype=np.intc)
        self._buffers = tuple(buffers)
        for buffer in self._buffers:
            if buffer.dtype != np.float64 or not buffer.flags.c_contiguous:
                raise ValueError("the tyre buffers must be C-contiguous float64 arrays")
        self._iw = np.zeros(max(tyres.sz_iw(), 1), dtype=np.longlong)
        self._w = np.zeros(max(tyres.sz_w(), 1))
        self._slots = np.array(mocap_slots, dtype=np.intc)
        self._model, self._data = model, data  # kept alive while their addresses are used
        entry = library.cosim_plant_advance
        entry.restype = ctypes.c_int
        pointer = ctypes.c_void_p
        self._entry = entry
        self._settle = library.cosim_plant_settle
        self._settle.restype = ctypes.c_int
        self._library = library
        self._fixed = (
            pointer(model._address), pointer(data._address))
        self._arrays = (
            self.state.ctypes.data_as(pointer), self._constants.ctypes.data_as(pointer),
            self._indices.ctypes.data_as(pointer),
            *(buffer.ctypes.data_as(pointer) for buffer in self._buffers),
            self._iw.ctypes.data_as(pointer), self._w.ctypes.data_as(pointer))

    def settle(self, n: int) -> bool:
        """``n`` of :meth:`cosim.plant.car.MujocoPlant._settle`'s steps (MuJoCo and the tyres,
        no actuator, no resistance) on the tyre loads in :attr:`state`; False when one ended
        with a MuJoCo warning or a non-finite or absurd state (the caller raises)."""
        return _finished(self._settle(*self._fixed, ctypes.c_int(n), *self._arrays), n)

    def state_reader(self, free_qpos: int, free_dof: int, steer_qpos: Sequence[int],
                     spin_dofs: Sequence[int]) -> StateReader:
        """The plant's state read in C from this library (:class:`StateReader`)."""
        return StateReader(self._library, self._data, free_qpos, free_dof, steer_qpos,
                           spin_dofs)

    def advance(self, n: int, poses: np.ndarray | None = None) -> bool:
        """``n`` physics steps; False when one ended with a MuJoCo warning or a
        non-finite or absurd state (the steps stop there: the caller raises). ``poses``:
        with traffic, the cars' mocap poses after each step, ``(n, cars, 7)``. Raises
        RuntimeError when the C step cannot go on (more tyre contacts than it holds, or
        the tyre function failed)."""
        n_cars = len(self._slots)
        if n_cars:
            if poses is None or poses.shape != (n, n_cars, 7):
                raise ValueError(f"advance({n}) with {n_cars} traffic cars needs their "
                                 f"poses, shape ({n}, {n_cars}, 7)")
            poses = np.ascontiguousarray(poses, dtype=float)
            traffic = (poses.ctypes.data_as(ctypes.c_void_p),
                       self._slots.ctypes.data_as(ctypes.c_void_p))
        else:
            traffic = (None, None)
        done = self._entry(*self._fixed, ctypes.c_int(n), *self._arrays, *traffic,
                           ctypes.c_int(n_cars))
        return _finished(done, n)


def _finished(done: int, n: int) -> bool:
    """Whether the C's ``n`` steps all ran (its return ``done``); RuntimeError when the C
    step could not go on."""
    if done == -1:
        raise RuntimeError("the compiled physics step failed (more tyre contacts than it "
                           "holds, or the tyre function reported an error)")
    return done == n


class StateReader:
    """:meth:`cosim.plant.car.MujocoPlant.state`'s numbers in one C call
    (``cosim_plant_state`` of ``plant_step.c``, the same expressions in the same order):
    ``reader(prev_linvel, inv_dt)`` gives x, y, z, roll, pitch, yaw, vx, vy, yaw rate, ax, ay,
    the road-wheel angle and the four spin rates of the data's current state."""

    def __init__(self, library: ctypes.CDLL, data: mujoco.MjData, free_qpos: int,
                 free_dof: int, steer_qpos: Sequence[int], spin_dofs: Sequence[int]) -> None:
        entry = library.cosim_plant_state
        pointer, double = ctypes.c_void_p, ctypes.c_double
        entry.argtypes = (pointer, pointer, double, double, double, double, pointer)
        entry.restype = ctypes.c_int
        self._addresses = np.array([free_qpos, free_dof, *steer_qpos, *spin_dofs],
                                   dtype=np.intc)
        if self._addresses.size != 8:
            raise ValueError("expected two steering joints and four spin dofs")
        self._out = np.zeros(16)
        self._entry, self._library, self._data = entry, library, data  # kept alive
        self._fixed = (data._address, self._addresses.ctypes.data)
        self._out_address = self._out.ctypes.data

    def __call__(self, prev_linvel: Sequence[float], inv_dt: float) -> list[float]:
        pvx, pvy, pvz = prev_linvel
        self._entry(*self._fixed, pvx, pvy, pvz, inv_dt, self._out_address)
        return self._out.tolist()
