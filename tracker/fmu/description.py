"""An FMU read and checked before any run: what it is, what it reads, what it returns.

:func:`describe` opens ``tracker.name = fmu:PATH`` with fmpy (``read_model_description``,
which validates ``modelDescription.xml`` against the FMI schema, and the archive's list of
binaries) and refuses, each in one line naming the FMU and what was expected:

- a missing file, a file that is not a zip archive, an invalid ``modelDescription.xml``,
  an FMI version other than 2 or 3;
- no co-simulation interface (an FMU for model exchange only: cosim does not integrate it);
- no binary for this platform, where fmpy loads it from (``binaries/linux64/ID.so`` for
  FMI 2, ``binaries/x86_64-linux/ID.so`` for FMI 3; FMI 2.0.4 section 2.3, FMI 3.0 section
  2.5.1);
- an input cosim cannot serve (:mod:`tracker.fmu.signals`), a missing output ``steer_rad``
  or ``accel_mps2``, a signal that is not a ``Real`` (FMI 2) or ``Float64`` (FMI 3), a unit
  that disagrees with the one the name implies (:mod:`tracker.fmu.units`), an estimate state
  the estimator does not have, a preview index out of range;
- a fixed communication step the control period is not a whole multiple of (FMI 3's
  ``fixedInternalStepSize``; an FMI 2 FMU that cannot vary its step and states its step as
  ``DefaultExperiment stepSize``): cosim steps the FMU once per ``sim.control_period_s``;
- a ``tracker.fmu.parameters`` entry that is no parameter of the FMU or has the wrong type.
"""

from __future__ import annotations

import difflib
import math
import struct
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import fmpy
from fmpy.model_description import ModelDescription, read_model_description

from cosim.core.exceptions import PluginError
from tracker.fmu.config import MAX_PREVIEW_POINTS, FmuConfig, fmu_path
from tracker.fmu.signals import OUTPUTS, implied_unit, parse_input
from tracker.fmu.units import unit_disagrees

FLOAT_TYPES = ("Real", "Float64")
"""The FMI 2 and FMI 3 type of every signal (IEEE 754 double)."""
INTEGER_TYPES = ("Integer", "Int32", "Int64")
"""Integer parameter types :mod:`tracker.fmu.slave` can set."""
STEP_TOLERANCE = 1e-9
"""Relative tolerance of "a whole multiple of the FMU's fixed step"."""


@dataclass(frozen=True)
class FmuVariable:
    """One variable of the FMU's model description."""

    name: str
    value_reference: int
    type: str
    """``Real`` / ``Integer`` / ``Boolean`` (FMI 2), ``Float64`` / ``Int32`` ... (FMI 3)."""
    causality: str
    unit: str | None


@dataclass(frozen=True)
class FmuParameter:
    """A value from ``tracker.fmu.parameters`` for a parameter of the FMU."""

    variable: FmuVariable
    value: float | int | bool


@dataclass(frozen=True)
class FmuDescription:
    """A checked co-simulation FMU: everything needed to load and drive it."""

    tracker_name: str
    """``fmu:PATH``, as configured (named in every message)."""
    path: Path
    fmi_major: int
    model_name: str
    model_identifier: str
    token: str
    """FMI 2 ``guid`` / FMI 3 ``instantiationToken``."""
    inputs: tuple[FmuVariable, ...]
    """Every input of the FMU, each a signal cosim serves, in declaration order."""
    steer: FmuVariable
    accel: FmuVariable
    parameters: tuple[FmuParameter, ...]
    fixed_step_s: float | None
    """The FMU's fixed communication step, if it has one [s]."""

    @property
    def binary_dir(self) -> str:
        """Where this platform's binary sits inside the archive."""
        return binary_dir(self.fmi_major)


def binary_dir(fmi_major: int) -> str:
    """The archive folder of this platform's binary for an FMI ``fmi_major`` FMU."""
    return f"binaries/{fmpy.platform if fmi_major == 2 else fmpy.platform_tuple}"


def describe(name: str, config: FmuConfig, control_period_s: float,
             state_names: tuple[str, ...] | None = None) -> FmuDescription:
    """Read and check the FMU ``name`` (``fmu:PATH``) for a run stepping it every
    ``control_period_s``; ``state_names`` are the estimator's states when known (module
    docstring). Raises :class:`PluginError` (one line) for a bad FMU."""
    check = _Check(name)
    model = check.model_description()
    version = model.fmiMajorVersion
    if version not in (2, 3):
        raise check.error(f"FMI {model.fmiVersion}: expected FMI 2 or FMI 3")
    if model.coSimulation is None:
        raise check.error("no co-simulation interface (model exchange only): expected an FMU "
                          "exported for co-simulation")
    identifier = model.coSimulation.modelIdentifier
    check.binary(version, identifier)
    variables = _variables(model)
    definitions = {unit.name: unit for unit in model.unitDefinitions}
    inputs = tuple(v for v in variables.values() if v.causality == "input")
    for variable in inputs:
        check.input(variable, definitions, state_names)
    steer, accel = (check.output(variables.get(s.name), s.name, definitions) for s in OUTPUTS)
    fixed_step_s = _fixed_step_s(model)
    if fixed_step_s is not None:
        ratio = control_period_s / fixed_step_s
        if abs(ratio - round(ratio)) > STEP_TOLERANCE * max(ratio, 1.0) or round(ratio) < 1:
            raise check.error(f"the FMU's communication step is fixed at {fixed_step_s:g} s: "
                              f"expected sim.control_period_s = {control_period_s:g} to be a "
                              "whole multiple of it")
    parameters = tuple(check.parameter(variables.get(key), key, value,
                                       [v.name for v in variables.values()
                                        if v.causality in ("parameter", "structuralParameter")])
                       for key, value in config.parameters.items())
    return FmuDescription(
        tracker_name=name, path=check.path, fmi_major=version,
        model_name=str(model.modelName), model_identifier=identifier, token=str(model.guid),
        inputs=inputs, steer=steer, accel=accel, parameters=parameters,
        fixed_step_s=fixed_step_s)


MAX_BINARY_BYTES = 256 * 1024 * 1024
"""The largest FMU binary cosim unpacks (a controller's library is kilobytes to megabytes;
an archive that unpacks to gigabytes is refused before it fills the disk)."""

ELF_X86_64 = 62
"""``e_machine`` of an x86-64 ELF file."""


def elf_problem(data: bytes) -> str:
    """Why ``data`` is no loadable x86-64 Linux shared library (``""`` when it looks like
    one): not ELF, another class or machine, not a shared object, or cut short before the
    end of the program or section headers its header announces (loading a truncated
    library crashes the loader with SIGBUS; the check is the header's own arithmetic)."""
    if data[:4] != b"\x7fELF":
        return "not an ELF file (a Linux shared library starts with \\x7fELF): expected " \
            "the FMU's library compiled for x86_64 Linux"
    if data[4] != 2 or data[5] != 1:
        return (f"an ELF file of class {'32' if data[4] == 1 else '?'}-bit, "
                f"{'little' if data[5] == 1 else 'big'}-endian: expected 64-bit "
                "little-endian (x86_64 Linux)")
    if len(data) < 64:
        return f"{len(data)} bytes, cut short inside its ELF header"
    e_type, e_machine = struct.unpack_from("<HH", data, 16)
    if e_machine != ELF_X86_64:
        return f"an ELF file for machine {e_machine}: expected x86-64 ({ELF_X86_64})"
    if e_type != 3:
        return f"an ELF file of type {e_type}: expected a shared object (type 3)"
    e_phoff, e_shoff = struct.unpack_from("<QQ", data, 32)
    e_phentsize, e_phnum, e_shentsize, e_shnum = struct.unpack_from("<HHHH", data, 54)
    needed = max(e_phoff + e_phentsize * e_phnum, e_shoff + e_shentsize * e_shnum)
    if needed > len(data):
        return (f"{len(data):,} bytes where its headers reach to byte {needed:,}: the "
                "library is truncated")
    return ""


def _variables(model: ModelDescription) -> dict[str, FmuVariable]:
    found = {}
    for v in model.modelVariables:
        unit = v.unit or (v.declaredType.unit if v.declaredType is not None else None)
        found[v.name] = FmuVariable(v.name, int(v.valueReference), str(v.type),
                                    str(v.causality), unit)
    return found


def _fixed_step_s(model: ModelDescription) -> float | None:
    """The step the FMU must be driven at (module docstring), if any."""
    cosim = model.coSimulation
    if cosim.fixedInternalStepSize:
        return float(cosim.fixedInternalStepSize)
    experiment = model.defaultExperiment
    if (not cosim.canHandleVariableCommunicationStepSize and experiment is not None
            and experiment.stepSize is not None):
        return float(experiment.stepSize)
    return None


class _Check:
    """The checks of :func:`describe`, each raising one line that names the FMU."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.given = fmu_path(name)
        self.path = Path(self.given).expanduser()

    def error(self, what: str) -> PluginError:
        return PluginError(f"tracker.name = {self.name!r}: {what}")

    def model_description(self) -> ModelDescription:
        if not self.given.strip():
            raise self.error("no path: expected fmu:PATH.fmu")
        if not self.path.is_file():
            what = "a folder" if self.path.is_dir() else "no such file"
            raise self.error(f"{what}: expected a co-simulation FMU (a .fmu file)")
        if not zipfile.is_zipfile(self.path):
            raise self.error("not a zip archive: expected an FMU (a zip with "
                             "modelDescription.xml and binaries)")
        try:
            return read_model_description(str(self.path))
        except Exception as error:  # fmpy raises plain Exceptions, lxml's and KeyError
            problem = str(error).strip().replace("Failed to validate modelDescription.xml:",
                                                 "").strip().lstrip("- ").splitlines()
            more = f" (and {len(problem) - 1} more)" if len(problem) > 1 else ""
            raise self.error(f"modelDescription.xml cannot be read: "
                             f"{(problem or [type(error).__name__])[0]}{more}") from None

    def binary(self, version: int, identifier: str) -> None:
        folder = binary_dir(version)
        member = f"{folder}/{identifier}{fmpy.sharedLibraryExtension}"
        with zipfile.ZipFile(self.path) as archive:
            if member in archive.namelist():
                info = archive.getinfo(member)
                if info.file_size > MAX_BINARY_BYTES:
                    raise self.error(f"{member} is {info.file_size:,} bytes unpacked: expected "
                                     f"a shared library of at most {MAX_BINARY_BYTES:,}")
                problem = elf_problem(archive.read(member))
                if problem:
                    raise self.error(f"{member} cannot be loaded: {problem}")
                return
        has = [p for p in fmpy.supported_platforms(str(self.path))]
        hint = (" (C sources only: compile them first, e.g. with fmpy's "
                "compile_platform_binary)" if has == ["c-code"] else "")
        raise self.error(f"no binary for this platform ({member}): the FMU has "
                         f"{', '.join(has) or 'none'}{hint}")

    def input(self, variable: FmuVariable, definitions: dict[str, Any],
              state_names: tuple[str, ...] | None) -> None:
        ref = parse_input(variable.name)
        if ref is None:
            raise self.error(f"input {variable.name!r} is not a signal cosim serves: expected "
                             "cte_m, heading_err_rad, speed_mps, ref_speed_mps, "
                             "curvature_1pm, path_s_m, est_<state>, preview_x_m[i] or "
                             "preview_y_m[i] (docs/fmu.md)")
        if ref.kind == "state" and state_names is not None and ref.key not in state_names:
            raise self.error(f"input {variable.name!r}: the estimator has no state "
                             f"{ref.key!r}: expected one of "
                             + ", ".join("est_" + s for s in state_names))
        if ref.kind.startswith("preview") and not 1 <= ref.index <= MAX_PREVIEW_POINTS:
            raise self.error(f"input {variable.name!r}: expected a preview index in "
                             f"[1, {MAX_PREVIEW_POINTS}]")
        self._signal(variable, "input", definitions)

    def output(self, variable: FmuVariable | None, name: str,
               definitions: dict[str, Any]) -> FmuVariable:
        if variable is None or variable.causality != "output":
            found = "" if variable is None else f" ({name!r} is {_a(variable.causality)})"
            raise self.error(f"no output {name!r}{found}: expected a Real (FMI 2) or Float64 "
                             f"(FMI 3) output {name!r} [{implied_unit(name)}]")
        self._signal(variable, "output", definitions)
        return variable

    def _signal(self, variable: FmuVariable, role: str, definitions: dict[str, Any]) -> None:
        if variable.type not in FLOAT_TYPES:
            raise self.error(f"{role} {variable.name!r} is {variable.type}: expected Real "
                             "(FMI 2) or Float64 (FMI 3)")
        problem = unit_disagrees(variable.unit, implied_unit(variable.name), definitions)
        if problem:
            raise self.error(f"{role} {variable.name!r}: {problem} (the unit its name "
                             "implies)")

    def parameter(self, variable: FmuVariable | None, key: str, value: Any,
                  known: list[str] | None = None) -> FmuParameter:
        where = f"tracker.fmu.parameters.{key}"
        if variable is None or variable.causality not in ("parameter", "structuralParameter"):
            what = "no such variable" if variable is None else _a(variable.causality)
            names = ", ".join(known or []) or "none: it has no parameters"
            close = difflib.get_close_matches(key, known or [], n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise PluginError(f"{where}: {what} in {self.name!r}{hint}: expected a parameter "
                              f"of the FMU: {names}")
        kind = variable.type
        if kind in FLOAT_TYPES and _is_number(value):
            return FmuParameter(variable, float(value))
        if kind in INTEGER_TYPES and isinstance(value, int) and not isinstance(value, bool):
            return FmuParameter(variable, value)
        if kind == "Boolean" and isinstance(value, bool):
            return FmuParameter(variable, value)
        expected = {**dict.fromkeys(FLOAT_TYPES, "a finite number"),
                    **dict.fromkeys(INTEGER_TYPES, "an integer"),
                    "Boolean": "true or false"}.get(kind)
        if expected is None:
            raise PluginError(f"{where}: a {kind} parameter: expected a Real/Float64, "
                              "Integer/Int32/Int64 or Boolean parameter (cosim sets no other)")
        raise PluginError(f"{where} = {value!r}: the FMU's parameter is {kind}: expected "
                          f"{expected}")


def _a(noun: str) -> str:
    """``an input``, ``a parameter``."""
    return ("an " if noun[:1] in "aeiou" else "a ") + noun


def _is_number(value: Any) -> bool:
    return (isinstance(value, (int, float)) and not isinstance(value, bool)
            and math.isfinite(value))
