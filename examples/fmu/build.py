"""Build the example tracker FMUs: a C Stanley law and a Python pure pursuit, FMI 2 and 3.

    python examples/fmu/build.py OUT_DIR        # writes the four FMUs, prints their paths
    cosim run lane-change --tracker fmu:OUT_DIR/stanley-fmi2.fmu

- ``stanley-fmi2.fmu``, ``stanley-fmi3.fmu``: ``stanley.c`` (and ``fmi_unused.c``) compiled
  with gcc against the FMI headers fmpy ships (``fmpy/c-code``), zipped with a
  ``modelDescription.xml`` written here from :data:`STANLEY_VARIABLES`.
- ``pure-pursuit-fmi2.fmu``, ``pure-pursuit-fmi3.fmu``: ``pure_pursuit_fmi2.py`` and
  ``pure_pursuit_fmi3.py`` built by pythonfmu and pythonfmu3 (each FMU runs the Python
  class inside the interpreter that loads it).

Needs gcc, fmpy, pythonfmu and pythonfmu3 (``pip install 'cosim[dev]'``). The tests and
``bench/fmu_step.py`` build their FMUs with these functions.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import uuid
import zipfile
from pathlib import Path
from xml.sax.saxutils import quoteattr

import fmpy

HERE = Path(__file__).resolve().parent
MODEL_IDENTIFIER = "stanley"

STANLEY_VARIABLES: tuple[tuple[str, int, str, str, float | None], ...] = (
    # name, value reference (stanley.c's enum), causality, unit, start
    ("cte_m", 0, "input", "m", 0.0),
    ("heading_err_rad", 1, "input", "rad", 0.0),
    ("speed_mps", 2, "input", "m/s", 0.0),
    ("ref_speed_mps", 3, "input", "m/s", 0.0),
    ("curvature_1pm", 4, "input", "1/m", 0.0),
    ("est_yaw_rate_radps", 5, "input", "rad/s", 0.0),
    ("steer_rad", 6, "output", "rad", None),
    ("accel_mps2", 7, "output", "m/s2", None),
    # Parameters: the same start values as stanley.c's new_model().
    ("gain_1ps", 8, "parameter", "1/s", 1.5),
    ("softening_mps", 9, "parameter", "m/s", 1.0),
    ("wheelbase_m", 10, "parameter", "m", 2.8),
    ("yaw_damping_s", 11, "parameter", "s", 0.1),
    ("speed_gain_1ps", 12, "parameter", "1/s", 1.0),
    ("fail_at_s", 13, "parameter", "s", -1.0),
    ("nan_at_s", 14, "parameter", "s", -1.0),
)
"""The C FMU's variables (docs/fmu.md has what each input means)."""

UNITS: dict[str, dict[str, int]] = {
    "m": {"m": 1}, "s": {"s": 1}, "rad": {"rad": 1}, "1/m": {"m": -1}, "1/s": {"s": -1},
    "m/s": {"m": 1, "s": -1}, "m/s2": {"m": 1, "s": -2}, "rad/s": {"rad": 1, "s": -1},
}
"""Unit definitions with their SI base units (FMI 2.0.4 section 2.2.2)."""

TIME_VALUE_REFERENCE = 100
"""FMI 3's independent variable ``time`` (stanley.c's ``VR_TIME``)."""


def _unit_definitions() -> str:
    units = "".join(
        f'    <Unit name="{name}"><BaseUnit '
        + " ".join(f'{symbol}="{power}"' for symbol, power in base.items()) + "/></Unit>\n"
        for name, base in UNITS.items())
    return f"  <UnitDefinitions>\n{units}  </UnitDefinitions>\n"


def stanley_model_description(fmi_version: int) -> str:
    """``modelDescription.xml`` of the C FMU for FMI ``fmi_version`` (2 or 3)."""
    token = "{" + str(uuid.uuid5(uuid.NAMESPACE_URL, f"cosim/stanley/fmi{fmi_version}")) + "}"
    outputs = [vr for _, vr, causality, _, _ in STANLEY_VARIABLES if causality == "output"]
    rows = []
    for name, vr, causality, unit, start in STANLEY_VARIABLES:
        variability = ' variability="fixed"' if causality == "parameter" else ""
        start_attr = "" if start is None else f' start="{start!r}"'
        if fmi_version == 2:
            rows.append(f'    <ScalarVariable name={quoteattr(name)} valueReference="{vr}" '
                        f'causality="{causality}"{variability}>'
                        f'<Real unit="{unit}"{start_attr}/></ScalarVariable>\n')
        else:
            rows.append(f'    <Float64 name={quoteattr(name)} valueReference="{vr}" '
                        f'causality="{causality}"{variability} unit="{unit}"{start_attr}/>\n')
    head = (f'<?xml version="1.0" encoding="UTF-8"?>\n<fmiModelDescription '
            f'fmiVersion="{fmi_version}.0" modelName="{MODEL_IDENTIFIER}" '
            + (f'guid="{token}"' if fmi_version == 2 else f'instantiationToken="{token}"')
            + ' variableNamingConvention="structured" description="Stanley law with a '
            'speed P-loop (cosim example)">\n'
            f'  <CoSimulation modelIdentifier="{MODEL_IDENTIFIER}" '
            'canHandleVariableCommunicationStepSize="true"/>\n'
            + _unit_definitions()
            + '  <DefaultExperiment startTime="0" stopTime="15" stepSize="0.05"/>\n'
            + "  <ModelVariables>\n")
    if fmi_version == 2:
        index = {vr: i + 1 for i, (_, vr, _, _, _) in enumerate(STANLEY_VARIABLES)}
        unknowns = "".join(f'      <Unknown index="{index[vr]}"/>\n' for vr in outputs)
        structure = (f"  <ModelStructure>\n    <Outputs>\n{unknowns}    </Outputs>\n"
                     f"    <InitialUnknowns>\n{unknowns}    </InitialUnknowns>\n"
                     "  </ModelStructure>\n")
    else:
        rows.insert(0, f'    <Float64 name="time" valueReference="{TIME_VALUE_REFERENCE}" '
                       'causality="independent" variability="continuous"/>\n')
        structure = ("  <ModelStructure>\n"
                     + "".join(f'    <Output valueReference="{vr}"/>\n' for vr in outputs)
                     + "".join(f'    <InitialUnknown valueReference="{vr}"/>\n'
                               for vr in outputs)
                     + "  </ModelStructure>\n")
    return head + "".join(rows) + "  </ModelVariables>\n" + structure + \
        "</fmiModelDescription>\n"


def binary_folder(fmi_version: int) -> str:
    """Where fmpy looks for this platform's binary (FMI 2: ``linux64``; FMI 3:
    ``x86_64-linux``)."""
    return fmpy.platform if fmi_version == 2 else fmpy.platform_tuple


def build_c_fmu(out_dir: Path, fmi_version: int) -> Path:
    """Compile ``stanley.c`` for FMI ``fmi_version`` and zip it: ``stanley-fmi{N}.fmu``."""
    headers = Path(fmpy.__file__).parent / "c-code"
    out = Path(out_dir) / f"stanley-fmi{fmi_version}.fmu"
    with tempfile.TemporaryDirectory(prefix="cosim-fmu-build-") as work:
        library = Path(work) / f"{MODEL_IDENTIFIER}{fmpy.sharedLibraryExtension}"
        subprocess.run(
            ["gcc", "-shared", "-fPIC", "-O2", "-std=c99", "-Wall", "-Wextra", "-Werror",
             f"-DFMI_VERSION={fmi_version}", f"-I{headers}", str(HERE / "stanley.c"),
             str(HERE / "fmi_unused.c"), "-o", str(library), "-lm"],
            check=True, capture_output=True, text=True)
        with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as archive:
            archive.writestr("modelDescription.xml", stanley_model_description(fmi_version))
            archive.write(library, f"binaries/{binary_folder(fmi_version)}/{library.name}")
    return out


def build_python_fmu(out_dir: Path, fmi_version: int) -> Path:
    """Build the pure-pursuit FMU for FMI ``fmi_version`` with pythonfmu (2) or pythonfmu3
    (3), in a child process (the builders import the script): ``pure-pursuit-fmi{N}.fmu``."""
    builder = "pythonfmu" if fmi_version == 2 else "pythonfmu3"
    script = HERE / f"pure_pursuit_fmi{fmi_version}.py"
    out = Path(out_dir) / f"pure-pursuit-fmi{fmi_version}.fmu"
    with tempfile.TemporaryDirectory(prefix="cosim-fmu-build-") as work:
        subprocess.run([sys.executable, "-m", builder, "build", "-f", str(script), "-d", work,
                        str(HERE / "pure_pursuit_law.py")],
                       check=True, capture_output=True, text=True, cwd=work)
        built = next(Path(work).glob("*.fmu"))
        built.replace(out)
    return out


def build_all(out_dir: Path) -> list[Path]:
    """The four example FMUs in ``out_dir`` (created if missing)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    return [build(out_dir, version) for build in (build_c_fmu, build_python_fmu)
            for version in (2, 3)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out_dir", type=Path, help="folder for the .fmu files")
    args = parser.parse_args()
    try:
        paths = build_all(args.out_dir)
    except subprocess.CalledProcessError as error:
        sys.exit(f"build.py: {' '.join(error.cmd[:3])} ... failed:\n{error.stderr}")
    for path in paths:
        print(path)


if __name__ == "__main__":
    main()
