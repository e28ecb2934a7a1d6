"""A table of bad inputs and faults: each gets its exit code, exactly one line on stderr that
names the culprit and what was expected, no traceback, and no file of the user's lost.

Rows call :func:`cosim.cli.main` in this process (each row's files are made fresh in
``tmp_path``); what only a separate process can show (a closed stdout, MUJOCO_GL, a full
disk, signals) is in ``test_faults.py``.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from mcap.writer import Writer

from cosim.cli import main


@dataclass(frozen=True)
class Files:
    """The files a row can name; ``user`` ones must be unchanged afterwards."""

    root: Path
    user: dict[str, Path] = field(default_factory=dict)

    def __call__(self, name: str) -> str:
        return str(self.root / name)


def _write_other_tool_mcap(path: Path) -> None:
    with path.open("wb") as stream:
        writer = Writer(stream)
        writer.start(profile="ros1", library="some-other-tool 1.0")
        schema = writer.register_schema(name="std_msgs/String", encoding="ros1msg",
                                        data=b"string data")
        channel = writer.register_channel(topic="/chatter", message_encoding="ros1",
                                          schema_id=schema)
        for i in range(3):
            writer.add_message(channel_id=channel, log_time=i, publish_time=i,
                               data=b"\x05\x00\x00\x00hello")
        writer.finish()


def _write_foreign_truth_mcap(path: Path) -> None:
    """Another tool's log on cosim's truth topic, without a position (nulls)."""
    with path.open("wb") as stream:
        writer = Writer(stream)
        writer.start(profile="", library="some-other-tool 1.0")
        schema = writer.register_schema(name="truth", encoding="jsonschema", data=b"{}")
        channel = writer.register_channel(topic="/vehicle/truth", message_encoding="json",
                                          schema_id=schema)
        for i in range(5):
            writer.add_message(channel_id=channel, log_time=i * 10**7, publish_time=i * 10**7,
                               data=b'{"t_s": %.2f, "x_m": null, "y_m": null}' % (i / 100))
        writer.finish()


def _write_empty_mcap(path: Path) -> None:
    with path.open("wb") as stream:
        writer = Writer(stream)
        writer.start(profile="", library="cosim 0.1.0")
        writer.finish()


def _loop(points: int = 40, radius_m: float = 50.0) -> list[tuple[float, float]]:
    return [(radius_m * math.cos(2 * math.pi * i / points),
             radius_m * math.sin(2 * math.pi * i / points)) for i in range(points)]


@pytest.fixture()
def files(tmp_path: Path) -> Files:
    root = tmp_path
    texts = {
        "good.yaml": "seed: 3\n",
        "latin1.yaml": None,
        "dup.yaml": "seed: 1\nplant:\n  mass_kg: 1500\n  mass_kg: 1600\n",
        "bomb.yaml": "plant:\n  mass_kg:\n    - &a [x, x, x, x, x, x, x, x, x]\n"
                     + "".join(f"    - &{b} [*{a}, *{a}, *{a}, *{a}, *{a}, *{a}, *{a}, *{a}]\n"
                               for a, b in zip("abcdefgh", "bcdefghi", strict=True)),
        "list.yaml": "- 1\n- 2\n",
        "broken.yaml": "plant: {mass_kg: 1500\n",
        "disabled-fault.yaml": "faults:\n  - {kind: dropout, sensor: heading}\n",
        "bad-channel.yaml": "faults:\n  - {kind: nan, sensor: imu, channel: nope}\n",
        "spec-dup.yaml": "scenario: lane-change\nseeds: 1\nseeds: 2\n",
        "spec-huge.yaml": "scenario: lane-change\nseeds: 10\ngrid:\n"
                          f"  plant.mass_kg: {list(range(1000, 2000, 10))}\n"
                          f"  plant.tyre_friction: {[0.5 + i / 100 for i in range(50)]}\n",
        "spec-latin1-scenario.yaml": "scenario: latin1.yaml\nseeds: 1\n",
        "spec-good.yaml": "scenario: lane-change\nseeds: 1\nduration_s: 0.1\n",
        # YAML aliases nine deep: 9^9 strings once expanded (a 58 MB summary, or worse)
        "spec-aliases.yaml": "scenario: lane-change\ndescription: &a9 ["
        + "".join(f"&a{k} [" for k in range(8, 0, -1)) + "x, x, x, x, x, x, x, x, x]"
        + "".join(f", *a{k}" * 8 + "]" for k in range(1, 9)) + "\n",
        "notes.txt": "not an MCAP file, just text\n",
        "one-point.csv": "x,y\n1,2\n",
        "huge.csv": "x,y\n" + "".join(f"{1e12 * x},{1e12 * y}\n" for x, y in _loop()),
        "open.csv": "x,y\n" + "".join(f"{x},0\n" for x in range(0, 100, 2))
                    + "".join(f"{x},50\n" for x in range(100, 0, -2)),
    }
    for name, text in texts.items():
        if text is not None:
            (root / name).write_text(text)
    (root / "latin1.yaml").write_bytes("description: Stra\xdfe\nseed: 1\n".encode("latin-1"))
    (root / "utf16.yaml").write_bytes("seed: 1\n".encode("utf-16"))
    (root / "binary.yaml").write_bytes(bytes(range(256)) * 4)
    (root / "spec-binary.yaml").write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(range(200)))
    (root / "existing.mcap").write_bytes(b"a user's precious log" * 100)
    (root / "a-file").write_text("a file where a directory is expected\n")
    _write_other_tool_mcap(root / "other.mcap")
    _write_empty_mcap(root / "empty.mcap")
    _write_foreign_truth_mcap(root / "foreign-truth.mcap")
    good = (root / "good.mcap")
    good.write_bytes((root / "other.mcap").read_bytes())
    corrupt = bytearray((root / "other.mcap").read_bytes())
    corrupt[40:200] = bytes(160)
    (root / "corrupt.mcap").write_bytes(bytes(corrupt))
    (root / "folder").mkdir()
    (root / "full").mkdir()
    (root / "full" / "results.csv").write_text("an earlier study's results\n")
    user = {name: root / name for name in (
        "good.yaml", "existing.mcap", "latin1.yaml", "binary.yaml", "a-file", "other.mcap",
        "corrupt.mcap", "spec-good.yaml", "full/results.csv")}
    return Files(root, user)


Args = Callable[[Files], list[str]]


def _fail_if(condition: str) -> Args:
    """A short run with one --fail-if condition (refused before the run when bad)."""
    return lambda f: ["run", "lane-change", "--duration", "0.1", "--fail-if", condition,
                      "--out", f("fail-if.mcap")]


@dataclass(frozen=True)
class Row:
    name: str
    args: Args
    fragments: tuple[str, ...]
    """Every one must be in the stderr line (the culprit, and what was expected)."""
    code: int = 2


ROWS = [
    # cosim run: scenario, config files and their encodings
    Row("unknown scenario", lambda f: ["run", "nowhere"], ("'nowhere'", "expected")),
    Row("config missing", lambda f: ["run", "lane-change", "--config", f("none.yaml")],
        ("none.yaml", "cannot read")),
    Row("config binary", lambda f: ["run", "lane-change", "--config", f("binary.yaml")],
        ("binary.yaml", "not UTF-8", "expected a UTF-8 text file")),
    Row("config latin-1", lambda f: ["run", "lane-change", "--config", f("latin1.yaml")],
        ("latin1.yaml", "byte 17 is not UTF-8")),
    Row("config utf-16", lambda f: ["run", "lane-change", "--config", f("utf16.yaml")],
        ("utf16.yaml", "expected a UTF-8 text file")),
    Row("config duplicate key", lambda f: ["run", "lane-change", "--config", f("dup.yaml")],
        ("dup.yaml", "line 4", "'mass_kg' given twice", "expected each key once")),
    Row("config YAML bomb", lambda f: ["run", "lane-change", "--config", f("bomb.yaml")],
        ("plant.mass_kg", "expected a number")),
    Row("config a list", lambda f: ["run", "lane-change", "--config", f("list.yaml")],
        ("list.yaml", "expected a mapping")),
    Row("config broken YAML", lambda f: ["run", "lane-change", "--config", f("broken.yaml")],
        ("broken.yaml", "not valid YAML")),
    Row("scenario file latin-1", lambda f: ["run", f("latin1.yaml")],
        ("latin1.yaml", "not UTF-8")),
    Row("scenario file utf-16", lambda f: ["run", f("utf16.yaml")], ("utf16.yaml", "UTF-8")),
    # --set
    Row("set without =", lambda f: ["run", "lane-change", "--set", "plant.mass_kg"],
        ("plant.mass_kg", "expected key.path=value")),
    Row("set unknown key", lambda f: ["run", "lane-change", "--set", "plant.mas_kg=1"],
        ("unknown key 'plant.mas_kg'", "did you mean 'plant.mass_kg'?",
         "`cosim config keys plant`")),
    Row("set key without its unit", lambda f: ["run", "lane-change", "--set", "plant.mass=1500"],
        ("unknown key 'plant.mass'", "did you mean 'plant.mass_kg'?")),
    Row("set key nothing like any", lambda f: ["run", "lane-change", "--set", "plant.zzz=1"],
        ("unknown key 'plant.zzz'", "expected one of", "mass_kg")),
    Row("set negative mass", lambda f: ["run", "lane-change", "--set", "plant.mass_kg=-5"],
        ("plant.mass_kg = -5", "expected a number in")),
    Row("set exponent out of range", lambda f: ["run", "lane-change", "--set",
                                                "plant.mass_kg=2e9"],
        ("plant.mass_kg = 2000000000.0", "expected a number in")),
    Row("set front track too narrow", lambda f: ["run", "lane-change", "--set",
                                                 "plant.track_front_m=0.3"],
        ("plant.track_front_m = 0.3", "expected 0 (track_m) or a track in [0.5, 3] m")),
    Row("set steering limit past the pole", lambda f: ["run", "lane-change", "--set",
                                                       "plant.max_steer_rad=1.6"],
        ("plant.max_steer_rad = 1.6", "expected a number in [0.05, 1.5]")),
    Row("set steering limit past the wheel's 90 deg",
        lambda f: ["run", "lane-change", "--set", "plant.max_steer_rad=1.3"],
        ("plant.max_steer_rad = 1.3", "expected less than 1.2925 rad",
         "inner front wheel's Ackermann angle reaches 90 deg")),
    Row("set friction scale zero", lambda f: ["run", "lane-change", "--set",
                                              "plant.tyre.lateral_friction_scale=0"],
        ("plant.tyre.lateral_friction_scale = 0", "expected a number in [0.1, 3]")),
    Row("set word for number", lambda f: ["run", "lane-change", "--set", "plant.mass_kg=heavy"],
        ("plant.mass_kg = 'heavy'", "expected a number")),
    Row("set huge value", lambda f: ["run", "lane-change", "--set", "plant.mass_kg=" + "9x" * 5000],
        ("plant.mass_kg = '9x9x", "expected a number")),
    Row("set rate off the step", lambda f: ["run", "lane-change", "--set",
                                            "sim.control_period_s=0.003"],
        ("sim.control_period_s = 0.003", "whole multiple")),
    Row("set duplicate key in value", lambda f: ["run", "lane-change", "--set",
                                                 "plant={mass_kg: 1, mass_kg: 2}"],
        ("--set", "'mass_kg' given twice")),
    Row("unknown tracker", lambda f: ["run", "lane-change", "--tracker", "bang-bang"],
        ("tracker.name = 'bang-bang'", "expected one of")),
    # trackers from outside cosim (tests/user_trackers.py)
    Row("plug-in module missing", lambda f: ["run", "lane-change", "--tracker",
                                             "no_such_pkg.mod:Tracker"],
        ("tracker.name = 'no_such_pkg.mod:Tracker'", "no module 'no_such_pkg' on Python's "
         "import path", "PYTHONPATH=. cosim")),
    Row("plug-in class missing", lambda f: ["run", "lane-change", "--tracker",
                                            "tests.user_trackers:Nope"],
        ("'tests.user_trackers:Nope'", "no attribute 'Nope'", "expected a class")),
    Row("plug-in not a class", lambda f: ["run", "lane-change", "--tracker",
                                          "tests.user_trackers:not_a_class"],
        ("'tests.user_trackers:not_a_class'", "expected a tracker class")),
    Row("plug-in without step", lambda f: ["run", "lane-change", "--tracker",
                                           "tests.user_trackers:NoStep"],
        ("'tests.user_trackers:NoStep'", "no step method",
         "expected step(t_s, estimate, reference) -> (Command, Plan)")),
    Row("plug-in wrong return type", lambda f: [
        "run", "lane-change", "--tracker", "tests.user_trackers:WrongReturn", "--duration",
        "0.2", "--out", f("wrong-return.mcap")],
        ("'tests.user_trackers:WrongReturn'", "step returned (Command)",
         "expected a Command, or a tuple (Command, Plan)")),
    Row("plug-in Command field a string", lambda f: [
        "run", "lane-change", "--tracker", "tests.user_trackers:StringAccel", "--duration",
        "0.1", "--out", f("string-accel.mcap")],
        ("'tests.user_trackers:StringAccel'", "Command.accel_mps2 = 'fast' (str)",
         "expected a finite number", "(the log up to it: ", "string-accel.mcap)")),
    Row("plug-in Command field an array", lambda f: [
        "run", "lane-change", "--tracker", "tests.user_trackers:ArraySteer", "--duration",
        "0.1", "--out", f("array-steer.mcap")],
        ("Command.steer_rad = array([0.1, 0.2]) (ndarray)", "expected a finite number")),
    Row("plug-in Plan of the wrong shape", lambda f: [
        "run", "lane-change", "--tracker", "tests.user_trackers:BadPlanStates", "--duration",
        "0.1", "--out", f("bad-plan.mcap")],
        ("Plan.states = an array of shape (2, 3)", "expected shape (rows, 1)")),
    Row("plug-in calls sys.exit", lambda f: [
        "run", "lane-change", "--tracker", "tests.user_trackers:Exiting", "--duration",
        "0.3", "--set", "tracker.params.fail_at_s=0.1", "--out", f("exiting.mcap")],
        ("run aborted (error)", "'tests.user_trackers:Exiting' called sys.exit(0)",
         "t = 0.100 s"), code=3),
    Row("plug-in params unknown key", lambda f: [
        "run", "lane-change", "--tracker", "tests.user_trackers:Straight",
        "--set", "tracker.params.gian=2"], ("tracker.params.gian", "expected one of")),
    Row("plug-in params out of range", lambda f: [
        "run", "lane-change", "--tracker", "tests.user_trackers:Straight",
        "--set", "tracker.params.sleep_s=-1"], ("tracker.params.sleep_s = -1", "expected")),
    Row("plug-in estimator without update", lambda f: [
        "run", "lane-change", "--estimator", "tests.user_trackers:Straight"],
        ("estimator.name = 'tests.user_trackers:Straight'", "lacks predict",
         "expected predict(t_s)")),
    Row("negative duration", lambda f: ["run", "lane-change", "--duration", "-1"],
        ("--duration -1.0", "expected a number of seconds")),
    Row("zero duration (ran and said ok)", lambda f: ["run", "lane-change", "--duration", "0"],
        ("--duration 0.0", "expected a number of seconds > 0")),
    Row("zero sim.duration_s", lambda f: ["run", "lane-change", "--set", "sim.duration_s=0"],
        ("sim.duration_s = 0", "expected a number in [0.001, 3600]")),
    Row("scenario with an underscore (no hint)", lambda f: ["run", "lane_change"],
        ("scenario 'lane_change'", "did you mean 'lane-change'?")),
    Row("config keys in American spelling (no hint)", lambda f: ["config", "keys", "plant.tire"],
        ("'plant.tire'", "did you mean 'plant.tyre'?")),
    Row("no command (only 'arguments are required')", lambda f: [],
        ("expected a command", "cosim run lane-change")),
    Row("plug-in importing a module from before the regroup", lambda f: [
        "run", "lane-change", "--tracker", "tests.old_path_tracker:Old"],
        ("needs the module 'cosim.records', which cosim moved to 'cosim.core.records'",)),
    Row("NaN duration", lambda f: ["run", "lane-change", "--duration", "nan"],
        ("--duration nan", "expected")),
    Row("seed not a number", lambda f: ["run", "lane-change", "--seed", "abc"],
        ("'abc'",)),
    Row("fault on a disabled sensor", lambda f: ["run", "lane-change", "--config",
                                                 f("disabled-fault.yaml")],
        ("faults[0].sensor = 'heading'", "disabled", "expected an enabled sensor")),
    Row("fault kind unknown", lambda f: ["run", "lane-change", "--set",
                                         "faults=[{kind: meltdown}]"],
        ("faults[0].kind = 'meltdown'", "expected one of")),
    Row("fail-if malformed", lambda f: ["run", "lane-change", "--fail-if", "cte_max_m~0.3"],
        ("--fail-if 'cte_max_m~0.3'", "expected METRIC OP VALUE")),
    Row("fail-if number with a unit", _fail_if("cte_max_m>0.3m"),
        ("'0.3m' is not a number", '(in m: 0.3)')),
    Row("set value nested 2000 deep", lambda f: ["run", "lane-change", "--set",
                                                 "plant.mass_kg=" + "[" * 2000 + "]" * 2000],
        ("nested deeper than 64 levels", "expected a configuration value")),  # RecursionError
    Row("set mapping nested 100 deep", lambda f: ["run", "lane-change", "--set",
                                                  "tracker.params=" + "{a: " * 100 + "1"
                                                  + "}" * 100],
        ("nested deeper than 64 levels",)),
    Row("live pace absurdly slow", lambda f: ["run", "lane-change", "--live", "--pace",
                                              "1e-300"],
        ("--pace 1e-300", "in [0.01, 1000]")),  # was an OverflowError
    Row("fail-if number in centimetres", _fail_if("cte_max_m>30cm"),
        ("'30cm' is not a number", '(in m: 0.3)')),
    Row("fail-if number in degrees", _fail_if("heading_err_max_rad>5deg"),
        ("'5deg' is not a number", '(in rad: 0.0872665)')),
    Row("fail-if doubled operator", _fail_if("cte_max_m>>0.3"),
        ("'>0.3' is not a number", 'expected cte_max_m > a finite number')),
    Row("fail-if order on a word", _fail_if("outcome<ok"),
        ('outcome is a word', 'expected == or !=')),
    Row("fail-if flag not true or false", _fail_if("completed==yes"),
        ("'yes'", 'expected true or false for completed')),
    Row("fail-if unknown metric", _fail_if("cte_mx_m>0.3"),
        ("unknown metric 'cte_mx_m'", "did you mean 'cte_max_m'?")),
    Row("fail-if unknown outcome", _fail_if("outcome==spinned"),
        ("'spinned' (did you mean 'spun'?)", 'expected one of ok,')),
    # traffic against the ego and the ACC's sensor
    Row("ACC with the radar off", lambda f: ["run", "acc-braking", "--set",
                                             "sensors.radar.enabled=false", "--out", f("a.mcap")],
        ("sensors.radar.enabled = false", "tracker.acc.enabled = true",
         "expected sensors.radar.enabled=true")),
    Row("traffic car inside the ego", lambda f: ["run", "acc", "--set", "traffic.lead.gap_m=0",
                                                 "--out", f("a.mcap")],
        ("traffic.lead: gap_m = 0", "starts inside the ego's body", "expected gap_m beyond")),
    Row("traffic car null", lambda f: ["run", "acc", "--set", "traffic.lead=null",
                                       "--out", f("a.mcap")],
        ("traffic.lead = null", "expected a mapping of the car's settings")),
    # cosim run: where the log goes
    Row("out exists", lambda f: ["run", "lane-change", "--out", f("existing.mcap")],
        ("existing.mcap", "exists", "--force")),
    Row("out is the config", lambda f: ["run", "lane-change", "--config", f("good.yaml"),
                                        "--out", f("good.yaml"), "--force"],
        ("good.yaml", "is the input file", "expected another file name")),
    Row("out is a folder", lambda f: ["run", "lane-change", "--out", f("folder")],
        ("folder", "is a folder", "expected a file name")),
    Row("out under a file", lambda f: ["run", "lane-change", "--duration", "0.1",
                                       "--out", f("a-file") + "/run.mcap"],
        ("a-file/run.mcap", "cannot write")),
    Row("fault channel unknown, existing log forced", lambda f: [
        "run", "lane-change", "--duration", "0.1", "--config", f("bad-channel.yaml"),
        "--out", f("existing.mcap"), "--force"],
        ("channel = 'nope'", "expected one of")),
    # circuit files (path.file)
    Row("track file a device", lambda f: ["run", "track", "--set", "path.file=/dev/zero",
                                          "--out", f("t.mcap")],
        ("path.file '/dev/zero'", "not a regular file", "expected a CSV file")),
    Row("track file of one point", lambda f: ["run", "track", "--set",
                                              f"path.file={f('one-point.csv')}",
                                              "--out", f("t.mcap")],
        ("one-point.csv", "1 distinct point(s), expected at least 3")),
    Row("track coordinates scaled by 1e12", lambda f: ["run", "track", "--set",
                                                      f"path.file={f('huge.csv')}",
                                                      "--out", f("t.mcap")],
        ("huge.csv", "coordinate beyond 1e+07 m", "expected metres")),
    Row("track file open but path.closed", lambda f: ["run", "track", "--set",
                                                      f"path.file={f('open.csv')}",
                                                      "--out", f("t.mcap")],
        ("open.csv", "last point is 50.0 m from its first", "path.closed=false")),
    Row("config keys of an unknown section", lambda f: ["config", "keys", "plnt"],
        ("config keys 'plnt'", "no key starts with it")),
    # cosim inspect and plot
    Row("inspect missing", lambda f: ["inspect", f("missing.mcap")],
        ("missing.mcap", "no such file")),
    Row("inspect a folder", lambda f: ["inspect", f("folder")],
        ("is a folder", "expected an MCAP log")),
    Row("plot a folder", lambda f: ["plot", f("folder"), "--out", f("plots")],
        ("is a folder", "expected an MCAP log")),
    Row("render a folder", lambda f: ["render", f("folder"), "--out", f("v.mp4")],
        ("is a folder", "expected an MCAP log")),
    Row("export a folder to ROS 2", lambda f: ["export", "--ros2", f("folder"),
                                               "--out", f("bag.mcap")],
        ("is a folder", "expected the MCAP log of a cosim run")),
    Row("inspect text file", lambda f: ["inspect", f("notes.txt")],
        ("notes.txt", "not an MCAP file")),
    Row("inspect corrupted", lambda f: ["inspect", f("corrupt.mcap")], ("corrupt.mcap",)),
    Row("inspect other tool's topic", lambda f: ["inspect", f("other.mcap"), "--topic",
                                                 "/chatter"],
        ("'/chatter'", "not JSON", "expected a log that cosim wrote")),
    Row("inspect unknown topic", lambda f: ["inspect", f("empty.mcap"), "--topic", "/x"],
        ("--topic '/x'", "expected one of")),
    Row("plot empty", lambda f: ["plot", f("empty.mcap"), "--out", f("plots")],
        ("empty.mcap", "nothing to plot")),
    Row("plot other tool's", lambda f: ["plot", f("other.mcap"), "--out", f("plots")],
        ("other.mcap", "nothing to plot")),
    Row("plot other tool's truth without positions", lambda f: [
        "plot", f("foreign-truth.mcap"), "--out", f("plots")],
        ("foreign-truth.mcap", "no /vehicle/truth message with a finite", "nothing to plot")),
    Row("plot corrupted", lambda f: ["plot", f("corrupt.mcap"), "--out", f("plots")],
        ("corrupt.mcap",)),
    # cosim sweep
    Row("sweep spec missing", lambda f: ["sweep", f("none.yaml")], ("none.yaml", "no such file")),
    Row("sweep spec binary", lambda f: ["sweep", f("spec-binary.yaml"), "--out", f("s1")],
        ("spec-binary.yaml", "not UTF-8")),
    Row("sweep spec description of aliases", lambda f: ["sweep", f("spec-aliases.yaml"),
                                                        "--out", f("s9")],
        ("spec-aliases.yaml", "description: a list: expected text")),
    Row("sweep spec duplicate key", lambda f: ["sweep", f("spec-dup.yaml"), "--out", f("s2")],
        ("spec-dup.yaml", "'seeds' given twice")),
    Row("sweep scenario latin-1", lambda f: ["sweep", f("spec-latin1-scenario.yaml"),
                                             "--out", f("s3")],
        ("latin1.yaml", "not UTF-8")),
    Row("sweep of 50 000 runs", lambda f: ["sweep", f("spec-huge.yaml"), "--out", f("s4")],
        ("50,000 runs", "expected at most 10,000", "--yes")),
    Row("sweep out is a file", lambda f: ["sweep", f("spec-good.yaml"), "--out", f("a-file")],
        ("a-file", "is a file", "expected a directory")),
    Row("sweep out unmakeable", lambda f: ["sweep", f("spec-good.yaml"), "--out",
                                           f("a-file") + "/sweep"],
        ("a-file/sweep", "cannot make the directory", "expected a writable place")),
    Row("sweep out not empty", lambda f: ["sweep", f("spec-good.yaml"), "--out", f("full")],
        ("full", "not empty (results.csv)", "--force", "--resume")),
    Row("compare out not empty", lambda f: ["compare", "--trackers", "pid", "--scenarios",
                                            "circle", "--duration", "0.1", "--out", f("full")],
        ("full", "not empty (results.csv)", "--force", "--resume")),
    Row("compare resume without a comparison", lambda f: [
        "compare", "--trackers", "pid", "--scenarios", "circle", "--out", f("folder"),
        "--resume"], ("folder", "holds no comparison to finish")),
    Row("sweep resume without out", lambda f: ["sweep", f("spec-good.yaml"), "--resume"],
        ("--resume", "expected --out DIR")),
    Row("sweep zero workers", lambda f: ["sweep", f("spec-good.yaml"), "--workers", "0",
                                         "--out", f("s5")],
        ("--workers 0", "expected a count >= 1")),
    # cosim identify
    Row("identify config binary", lambda f: ["identify", "--config", f("binary.yaml")],
        ("binary.yaml", "not UTF-8")),
    Row("identify set exponent word", lambda f: ["identify", "--set", "plant.mass_kg=1e"],
        ("plant.mass_kg = '1e'", "expected a number")),
]


def _digests(files: Files) -> dict[str, str]:
    return {name: hashlib.sha256(path.read_bytes()).hexdigest()
            for name, path in files.user.items()}


def _call(argv: list[str]) -> int:
    try:
        return main(argv)
    except SystemExit as exit_:  # argparse's own usage errors
        return int(exit_.code or 0)


@pytest.mark.parametrize("row", ROWS, ids=[row.name for row in ROWS])
def test_bad_input(row: Row, files: Files, capsys: pytest.CaptureFixture[str]) -> None:
    before = _digests(files)
    code = _call(row.args(files))
    err = capsys.readouterr().err
    assert code == row.code, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert "Traceback" not in err
    assert len(lines[0]) < 600, "the echoed value must be capped"
    for fragment in row.fragments:
        assert fragment in lines[0], lines[0]
    assert _digests(files) == before, "a user's file changed"
    assert not list(files.root.glob(".*.partial")), "a temporary log was left behind"


def test_the_table_has_at_least_forty_rows() -> None:
    assert len(ROWS) >= 40
    assert len({row.name for row in ROWS}) == len(ROWS)
