"""Bad FMUs: one line and exit 2 before any run, or a run that ends with the reason named.

Each bad FMU is the working C FMU (examples/fmu/stanley.c) with one thing broken.
"""

from __future__ import annotations

import os
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from cosim.cli import main
from cosim.core.exceptions import PluginError
from cosim.log.reader import read_summary
from cosim.simulation.runner import run
from cosim.simulation.scenario_config import load_config

Edit = Callable[[str], str]


def rewritten(fmu: Path, out: Path, edit: Edit = lambda xml: xml,
              keep: Callable[[str], bool] = lambda name: True) -> Path:
    """A copy of ``fmu`` with its model description edited and some members left out."""
    with zipfile.ZipFile(fmu) as source, zipfile.ZipFile(out, "w") as target:
        for name in source.namelist():
            if not keep(name):
                continue
            data = source.read(name)
            if name == "modelDescription.xml":
                data = edit(data.decode()).encode()
            target.writestr(name, data)
    return out


def replaced(old: str, new: str) -> Edit:
    def edit(xml: str) -> str:
        assert old in xml, old
        return xml.replace(old, new)
    return edit


DEG_UNIT = '<Unit name="deg"><BaseUnit rad="1" factor="0.017453292519943295"/></Unit>'

BAD_DESCRIPTIONS: dict[str, tuple[int, Edit, str]] = {
    # case: (FMI version, edit of the model description, what the one line says)
    "model exchange only": (2, replaced(
        '<CoSimulation modelIdentifier="stanley" canHandleVariableCommunicationStepSize='
        '"true"/>', '<ModelExchange modelIdentifier="stanley"/>'),
        "no co-simulation interface (model exchange only)"),
    "missing output": (2, replaced('name="steer_rad"', 'name="steering_rad"'),
                       "no output 'steer_rad'"),
    "output of the wrong type": (3, replaced('<Float64 name="accel_mps2"',
                                             '<Float32 name="accel_mps2"'),
                                 "output 'accel_mps2' is Float32: expected Real"),
    "unit that disagrees": (2, lambda xml: replaced('<UnitDefinitions>',
                                                    f'<UnitDefinitions>{DEG_UNIT}')(xml)
                            .replace('<ScalarVariable name="heading_err_rad" valueReference='
                                     '"1" causality="input"><Real unit="rad"',
                                     '<ScalarVariable name="heading_err_rad" valueReference='
                                     '"1" causality="input"><Real unit="deg"'),
                            "input 'heading_err_rad': unit 'deg' is 0.0174533 x base units: "
                            "expected rad"),
    "input cosim does not serve": (3, replaced('name="cte_m"', 'name="lane_offset_m"'),
                                   "input 'lane_offset_m' is not a signal cosim serves"),
    "state the estimator lacks": (2, replaced('name="est_yaw_rate_radps"',
                                              'name="est_wind_mps"'),
                                  "the estimator has no state 'wind_mps'"),
    "fixed step that does not divide the period": (3, replaced(
        'canHandleVariableCommunicationStepSize="true"',
        'canHandleVariableCommunicationStepSize="false" fixedInternalStepSize="0.03"'),
        "communication step is fixed at 0.03 s: expected sim.control_period_s = 0.05"),
    "broken model description": (2, lambda xml: xml[: len(xml) // 2],
                                 "modelDescription.xml cannot be read"),
}


def refusal(fmu: Path | str, tmp_path: Path, capsys: pytest.CaptureFixture[str],
            *extra: str) -> str:
    """Run ``fmu`` through the CLI; assert exit 2, one line, no log; return the line."""
    out = tmp_path / "run.mcap"
    code = main(["run", "lane-change", "--tracker", f"fmu:{fmu}", "--out", str(out), *extra])
    err = capsys.readouterr().err
    assert code == 2, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert not out.exists() and not list(tmp_path.glob(".run.mcap*")), "a log was written"
    return err.strip()


@pytest.mark.parametrize("case", list(BAD_DESCRIPTIONS))
def test_a_bad_model_description_is_one_line_and_exit_2(
        case: str, c_fmus: dict[int, Path], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    version, edit, fragment = BAD_DESCRIPTIONS[case]
    bad = rewritten(c_fmus[version], tmp_path / "bad.fmu", edit)
    line = refusal(bad, tmp_path, capsys)
    assert line.startswith(f"cosim: error: tracker.name = 'fmu:{bad}': "), line
    assert fragment in line, line


def test_not_a_zip(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    fake = tmp_path / "controller.fmu"
    fake.write_text("a text file, not an FMU\n")
    assert "not a zip archive: expected an FMU" in refusal(fake, tmp_path, capsys)
    assert fake.read_text() == "a text file, not an FMU\n"


def test_missing_file_folder_or_path(tmp_path: Path,
                                     capsys: pytest.CaptureFixture[str]) -> None:
    assert "no such file: expected a co-simulation FMU" in refusal(
        tmp_path / "nowhere.fmu", tmp_path, capsys)
    assert "a folder: expected a co-simulation FMU" in refusal(tmp_path, tmp_path, capsys)
    assert "'fmu:': no path: expected fmu:PATH.fmu" in refusal("", tmp_path, capsys)


def test_no_binary_for_this_platform(c_fmus: dict[int, Path], tmp_path: Path,
                                     capsys: pytest.CaptureFixture[str]) -> None:
    bad = rewritten(c_fmus[2], tmp_path / "bad.fmu", keep=lambda n: "binaries" not in n)
    line = refusal(bad, tmp_path, capsys)
    assert "no binary for this platform (binaries/linux64/stanley.so): the FMU has none" in line


def test_a_binary_for_another_fmi_version_layout_is_no_binary(
        c_fmus: dict[int, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """An FMI 3 FMU whose binary sits where FMI 2 puts it cannot be loaded: refused."""
    with zipfile.ZipFile(c_fmus[3]) as source, \
            zipfile.ZipFile(tmp_path / "bad.fmu", "w") as target:
        for name in source.namelist():
            target.writestr(name.replace("x86_64-linux", "linux64"), source.read(name))
    line = refusal(tmp_path / "bad.fmu", tmp_path, capsys)
    assert "no binary for this platform (binaries/x86_64-linux/stanley.so)" in line


def _with_binary(fmu: Path, out: Path, change: Any) -> Path:
    """``fmu`` with its platform binary replaced by ``change(bytes)``."""
    with zipfile.ZipFile(fmu) as source, zipfile.ZipFile(out, "w") as target:
        for name in source.namelist():
            data = source.read(name)
            target.writestr(name, change(data) if name.startswith("binaries/") and
                            name.endswith(".so") else data)
    return out


@pytest.mark.parametrize(("change", "fragment"), [
    (lambda data: b"this is not a library\n", "cannot be loaded: not an ELF file"),
    (lambda data: data[:4] + b"\x01" + data[5:], "an ELF file of class 32-bit"),
    (lambda data: data[: len(data) // 2], "the library is truncated"),
])
def test_a_binary_that_cannot_load_is_refused_before_the_run(
        change: Any, fragment: str, c_fmus: dict[int, Path], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    """Loading these crashed the run: a traceback (wrong ELF class, a text file) or SIGBUS
    with nothing printed (a truncated library, exit 135)."""
    bad = _with_binary(c_fmus[2], tmp_path / "bad.fmu", change)
    assert fragment in refusal(bad, tmp_path, capsys)


@pytest.mark.parametrize(("setting", "fragment"), [
    ("tracker.fmu.parameters.stiffness=3",
     "tracker.fmu.parameters.stiffness: no such variable in"),
    ("tracker.fmu.parameters.gain=2",  # the FMU's own parameters are listed
     "(did you mean 'gain_1ps'?): expected a parameter of the FMU: gain_1ps, softening_mps,"),
    ("tracker.fmu.parameters.cte_m=1", "tracker.fmu.parameters.cte_m: an input in"),
    ("tracker.fmu.parameters.gain_1ps=true",
     "tracker.fmu.parameters.gain_1ps = True: the FMU's parameter is Real: expected a "
     "finite number"),
])
def test_bad_parameters_are_refused(setting: str, fragment: str, c_fmus: dict[int, Path],
                                    tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert fragment in refusal(c_fmus[2], tmp_path, capsys, "--set", setting)


def test_a_refused_fmu_leaves_an_existing_log_alone(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "mine.mcap"
    out.write_bytes(b"the user's earlier log")
    fake = tmp_path / "controller.fmu"
    fake.write_text("not an FMU")
    code = main(["run", "lane-change", "--tracker", f"fmu:{fake}", "--out", str(out),
                 "--force"])
    assert code == 2 and "not a zip archive" in capsys.readouterr().err
    assert out.read_bytes() == b"the user's earlier log"


def test_a_fixed_step_that_divides_the_period_is_accepted(c_fmus: dict[int, Path],
                                                          tmp_path: Path) -> None:
    fine = rewritten(c_fmus[3], tmp_path / "fixed.fmu", replaced(
        'canHandleVariableCommunicationStepSize="true"',
        'canHandleVariableCommunicationStepSize="false" fixedInternalStepSize="0.01"'))
    assert load_config("lane-change", tracker=f"fmu:{fine}").tracker.name == f"fmu:{fine}"
    with pytest.raises(PluginError, match="whole multiple"):
        load_config("lane-change", tracker=f"fmu:{fine}",
                    overrides=["sim.control_period_s=0.036"])


@pytest.mark.parametrize(("version", "parameter", "reason"), [
    (2, "fail_at_s", "failed at t = 0.500 s: fmi2DoStep failed with status 3 (error). "
                     "(the FMU said: fail_at_s reached: this FMU fails on purpose)"),
    (3, "fail_at_s", "failed at t = 0.500 s: fmi3DoStep failed with status 3 (error). "
                     "(the FMU said: fail_at_s reached: this FMU fails on purpose)"),
    (2, "nan_at_s", "returned a non-finite output at t = 0.500 s (steer_rad = nan"),
])
def test_an_fmu_that_fails_during_the_run_ends_it_with_the_reason(
        version: int, parameter: str, reason: str, c_fmus: dict[int, Path], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    name = f"fmu:{c_fmus[version]}"
    setting = f"tracker.fmu.parameters.{parameter}=0.5"
    config = load_config("lane-change", tracker=name, duration_s=1.0, overrides=[setting])
    result = run(config, tmp_path / "api.mcap")
    assert not result.completed and result.metrics["outcome"] == "error"
    assert result.reason.startswith(f"tracker {name!r} {reason}"), result.reason
    summary = read_summary(tmp_path / "api.mcap")  # the log is complete up to the abort
    assert not summary.truncated
    assert summary.metrics is not None and summary.metrics["completed"] is False
    assert summary.metrics["abort_reason"] == result.reason
    assert 0.45 < summary.duration_s < 0.6
    code = main(["run", "lane-change", "--tracker", name, "--duration", "1", "--set", setting,
                 "--out", str(tmp_path / "cli.mcap")])
    err = capsys.readouterr().err
    assert code == 3 and reason in err and "Traceback" not in err


def test_an_fmu_folder_left_by_a_dead_process_is_removed(tmp_path: Path,
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """A run that died (a crash, ``os._exit``, ``kill -9``) left its extracted FMU in the
    temporary folder for good; the next FMU's load removes it, and only it."""
    import subprocess

    from tracker.fmu import slave

    monkeypatch.setattr(slave.tempfile, "tempdir", str(tmp_path))
    dead = subprocess.Popen(["true"])
    dead.wait()
    orphan = tmp_path / f"cosim-fmu-{dead.pid}-x1"
    alive = tmp_path / f"cosim-fmu-{os.getppid()}-x2"
    foreign = tmp_path / "cosim-fmu-abc"
    for folder in (orphan, alive, foreign):
        (folder / "binaries").mkdir(parents=True)
    made = Path(slave._make_unzip_dir("cosim-fmu-"))
    assert made.parent == tmp_path and made.name.startswith(f"cosim-fmu-{os.getpid()}-")
    assert not orphan.exists() and alive.exists() and foreign.exists()


def _misbehaving_python_fmu(tmp_path: Path, name: str, misbehaviour: str) -> str:
    """The example pure-pursuit FMU (FMI 2, pythonfmu) as class ``name``, whose ``do_step``
    runs ``misbehaviour`` from t = 0.5 s on: its ``fmu:`` tracker name."""
    import subprocess
    import sys

    examples = Path(__file__).resolve().parents[3] / "examples" / "fmu"
    script = (examples / "pure_pursuit_fmi2.py").read_text().replace(
        "class PurePursuitFmi2", f"class {name}").replace(
        "    def do_step(self, current_time, step_size):\n",
        "    def do_step(self, current_time, step_size):\n"
        "        if current_time >= 0.5:\n"
        f"            {misbehaviour}\n")
    (tmp_path / "misbehaving_fmi2.py").write_text(script)
    law = tmp_path / "pure_pursuit_law.py"
    law.write_text((examples / law.name).read_text())
    subprocess.run([sys.executable, "-m", "pythonfmu", "build", "-f", "misbehaving_fmi2.py",
                    "-d", str(tmp_path), law.name], check=True, capture_output=True,
                   cwd=tmp_path)
    return f"fmu:{tmp_path / f'{name}.fmu'}"


def _cosim_run(tmp_path: Path, *args: str) -> Any:
    """``cosim run lane-change`` in a process of its own (the command as a user runs it)."""
    import subprocess
    import sys

    return subprocess.run([str(Path(sys.executable).with_name("cosim")), "run", "lane-change",
                           *args], capture_output=True, text=True, timeout=600)


def test_a_python_fmus_own_error_text_is_kept(tmp_path: Path) -> None:
    """A pythonfmu FMU whose ``do_step`` raises: before, the run said only "fmi2DoStep failed
    with status 4 (fatal)" (the FMU was instantiated with logging off, so it said nothing)."""
    name = _misbehaving_python_fmu(tmp_path, "RaisingFmi2",
                                   "raise ValueError('the lookahead table ran out')")
    done = _cosim_run(tmp_path, "--tracker", name, "--duration", "1", "--out",
                      str(tmp_path / "raising.mcap"))
    err = done.stderr
    assert done.returncode == 3 and "Traceback" not in err
    assert "failed at t = 0.500 s" in err
    assert "(the FMU said: ValueError('the lookahead table ran out'))" in err


def test_a_fatal_fmu_is_not_freed_so_the_process_runs_on(tmp_path: Path) -> None:
    """After ``fatal`` no FMI call is allowed (FMI 2.0.4 section 2.1.3). Before, the instance
    was freed and its library unloaded: the next run in the same process (a notebook, the
    API) died of a segmentation fault in a garbage collection."""
    import subprocess
    import sys

    name = _misbehaving_python_fmu(tmp_path, "RaisingFmi2",
                                   "raise ValueError('the lookahead table ran out')")
    program = (
        "import gc\n"
        "from cosim.cli import main\n"
        "for i in range(3):\n"
        f"    code = main(['run', 'lane-change', '--tracker', {name!r}, '--duration', '1',\n"
        f"                 '--out', {str(tmp_path)!r} + f'/run{{i}}.mcap'])\n"
        "    assert code == 3, code\n"
        "    gc.collect()\n"
        "print('survived')\n")
    done = subprocess.run([sys.executable, "-c", program], capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 0 and "survived" in done.stdout, done.returncode


def test_a_python_fmu_that_ends_the_process_is_named_and_the_log_kept(tmp_path: Path) -> None:
    """Before: exit 7, nothing printed, the log lost (then, with the guard, the log up to
    its last complete chunk; now finished by the parent, which writes it)."""
    name = _misbehaving_python_fmu(tmp_path, "ExitingFmi2", "import os; os._exit(7)")
    out = tmp_path / "exiting.mcap"
    done = _cosim_run(tmp_path, "--tracker", name, "--duration", "2", "--out", str(out))
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 3 and len(lines) == 1, done.stderr
    assert "the run's process died" in lines[0] and "exit status 7" in lines[0]
    assert f"the tracker {name!r} is an FMU" in lines[0]
    summary = read_summary(out)
    assert not summary.truncated and "config_json" in summary.metadata["run"]
    assert "every message the run sent" in lines[0]
