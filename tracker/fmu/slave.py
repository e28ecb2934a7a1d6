"""A checked FMU loaded and driven through fmpy's co-simulation API, FMI 2 or FMI 3 alike.

Life cycle (FMI 2.0.4 section 4.2.4, FMI 3.0 section 4.2): the archive is extracted to a
temporary folder; the instance is created (``fmi2Instantiate`` / ``fmi3InstantiateCoSimulation``
without event mode or early return), ``tracker.fmu.parameters`` are set, the start time is
0 (``fmi2SetupExperiment``, or the arguments of ``fmi3EnterInitializationMode``), and the
instance leaves initialisation mode in step mode. Each :meth:`FmuSlave.step` sets the
inputs, calls ``doStep(t, h)`` and reads ``steer_rad`` and ``accel_mps2``; :meth:`close`
terminates and frees the instance, unloads the library and removes the folder (also when
the slave is dropped without it, through :func:`weakref.finalize`).

fmpy raises on an FMI call that returns ``discard``, ``error`` or ``fatal``; the FMU's log
messages (its logger callback) are kept, the last few, so that the caller can name the
FMU's own reason. Nothing is printed.

After a ``fatal`` status "it is not possible to call any other function for any of the FMU
instances" (FMI 2.0.4 section 2.1.3; FMI 3.0 section 2.2.3): :meth:`close` then neither
terminates nor frees the instance and leaves the library loaded until the process ends. A
pythonfmu instance whose ``do_step`` raised, freed and unloaded, crashed the next run of the
same process (a segmentation fault in a later garbage collection).
"""

from __future__ import annotations

import collections
import ctypes
import os
import shutil
import tempfile
import weakref
from pathlib import Path
from typing import Any

import fmpy
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (
    FMU2Slave,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
)
from fmpy.fmi3 import FMU3Slave

from tracker.fmu.description import FLOAT_TYPES, INTEGER_TYPES, FmuDescription

LOG_LINES_KEPT = 5
"""How many of the FMU's latest log messages are kept for error messages."""
LOG_STATUS = ("ok", "warning", "discard", "error", "fatal", "pending")
"""FMI status codes, by value (fmi2Status / fmi3Status)."""
FATAL_STATUS = LOG_STATUS.index("fatal")


class FmuSlave:
    """One instance of the FMU, initialised at t = 0 and ready to step."""

    def __init__(self, description: FmuDescription) -> None:
        self.description = description
        self.messages: collections.deque[tuple[str, str]] = collections.deque(
            maxlen=LOG_LINES_KEPT)
        """The FMU's latest log messages, ``(status, text)``."""
        self._unzip_dir = _make_unzip_dir(prefix="cosim-fmu-")
        self._cleanup = weakref.finalize(self, shutil.rmtree, self._unzip_dir, True)
        self._inputs = [v.value_reference for v in description.inputs]
        self._outputs = [description.steer.value_reference, description.accel.value_reference]
        self._fmu: Any = None
        self._fatal = False
        """An FMI call returned ``fatal``: no further call, no unloading."""
        try:
            fmpy.extract(str(description.path), self._unzip_dir)
            self._instantiate()
        except BaseException:
            self.close()
            raise

    def _instantiate(self) -> None:
        d = self.description
        common = {"guid": d.token, "unzipDirectory": self._unzip_dir,
                  "modelIdentifier": d.model_identifier, "instanceName": "tracker"}
        if d.fmi_major == 2:
            self._fmu = FMU2Slave(**common)
            self._callbacks = _fmi2_callbacks(self._log2)
            self._fmu.instantiate(callbacks=self._callbacks, loggingOn=True)
            self._set_parameters()
            self._fmu.setupExperiment(startTime=0.0)
            self._fmu.enterInitializationMode()
            self._fmu.exitInitializationMode()
            self._set, self._get = self._fmu.setReal, self._fmu.getReal
        else:
            self._fmu = FMU3Slave(**common)
            self._fmu.instantiate(loggingOn=True, logMessage=self._log3)
            self._set_parameters()
            self._fmu.enterInitializationMode(startTime=0.0)
            self._fmu.exitInitializationMode()
            self._set, self._get = self._fmu.setFloat64, self._fmu.getFloat64

    def _set_parameters(self) -> None:
        fmu = self._fmu
        for parameter in self.description.parameters:
            vr, kind, value = ([parameter.variable.value_reference],
                               parameter.variable.type, parameter.value)
            if kind in FLOAT_TYPES:
                (fmu.setReal if kind == "Real" else fmu.setFloat64)(vr, [value])
            elif kind in INTEGER_TYPES:
                setter = {"Integer": "setInteger", "Int32": "setInt32", "Int64": "setInt64"}
                getattr(fmu, setter[kind])(vr, [value])
            else:
                fmu.setBoolean(vr, [value])

    def step(self, t_s: float, h_s: float, inputs: list[float]) -> tuple[float, float]:
        """Set the inputs, advance the FMU from ``t_s`` by ``h_s``, return
        ``(steer_rad, accel_mps2)``; fmpy raises when a call fails."""
        if self._inputs:
            self._set(self._inputs, inputs)
        try:
            result = self._fmu.doStep(t_s, h_s)
        except FMICallException as error:
            self._fatal = error.status == FATAL_STATUS
            raise
        if self.description.fmi_major == 3 and result[1]:  # terminateSimulation
            raise RuntimeError(f"the FMU asked to terminate at t = {t_s + h_s:g} s")
        steer, accel = self._get(self._outputs)
        return float(steer), float(accel)

    def last_message(self) -> str:
        """The FMU's last log message, its last line ("" if it logged nothing)."""
        if not self.messages:
            return ""
        lines = self.messages[-1][1].strip().splitlines()
        return lines[-1] if lines else ""

    def close(self) -> None:
        """Terminate and free the instance, unload the library, remove the folder."""
        fmu, self._fmu = self._fmu, None
        try:
            if fmu is not None and getattr(fmu, "component", None) and not self._fatal:
                try:
                    fmu.terminate()
                except Exception:  # an FMU that failed may refuse to terminate
                    pass
                fmu.freeInstance()
        finally:
            self._cleanup()

    def _log2(self, env: Any, instance: bytes, status: int, category: bytes,
              message: bytes) -> None:
        self._log(status, message)

    def _log3(self, env: Any, status: int, category: bytes, message: bytes) -> None:
        self._log(status, message)

    def _log(self, status: int, message: bytes | None) -> None:
        label = LOG_STATUS[status] if 0 <= status < len(LOG_STATUS) else str(status)
        text = (message or b"").decode("utf-8", "replace")
        self.messages.append((label, text))


def _make_unzip_dir(prefix: str) -> str:
    """A new private folder for the extracted FMU (:func:`tempfile.mkdtemp`), named with
    this process's id; the folders of processes that died without removing theirs (a
    crash, ``os._exit``, ``kill -9``) are removed first (:func:`_remove_orphans`)."""
    _remove_orphans(prefix)
    return tempfile.mkdtemp(prefix=f"{prefix}{os.getpid()}-")


def _remove_orphans(prefix: str) -> None:
    """Remove ``PREFIX<pid>-*`` folders in the temporary folder whose process has ended.
    A folder of a live process (or of a pid now reused) is left alone."""
    root = Path(tempfile.gettempdir())
    for folder in root.glob(f"{prefix}*-*"):
        pid = folder.name[len(prefix):].split("-", 1)[0]
        if not pid.isdigit() or _alive(int(pid)):
            continue
        shutil.rmtree(folder, ignore_errors=True)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return True


def _fmi2_callbacks(logger: Any) -> fmi2CallbackFunctions:
    """FMI 2 callbacks with ``logger`` behind fmpy's native proxy (which formats the
    variadic arguments ctypes cannot pass to Python) and the C library's allocator."""
    from fmpy.logging import addLoggerProxy

    callbacks = fmi2CallbackFunctions()
    callbacks.logger = fmi2CallbackLoggerTYPE(logger)
    callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(fmpy.calloc)
    callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(fmpy.free)
    addLoggerProxy(ctypes.byref(callbacks))
    return callbacks
