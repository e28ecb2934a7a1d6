"""The ``cosim`` command line.

cosim simulates a car (MuJoCo, Magic Formula tyres) driven by an MPC path tracker that sees
only a Kalman filter's estimate from noisy sensors, and logs every signal to one MCAP file.
Start with `cosim run lane-change`, then `cosim plot` or `cosim inspect` on the log it names.

    cosim run SCENARIO [--config FILE.yaml] [--tracker NAME] [--estimator NAME]
                       [--seed N] [--duration S] [--set key.path=value ...] [--out FILE.mcap]
                       [--force] [--fail-if 'METRIC>VALUE' ...] [--video FILE.mp4]
    cosim inspect FILE.mcap [--json] [--topic T [--head N]] [--csv DIR]
    cosim plot FILE.mcap [FILE2.mcap] [--out DIR]
    cosim scenarios
    cosim trackers
    cosim estimators
    cosim identify [--config FILE.yaml] [--set key.path=value ...] [--json]
    cosim sweep SPEC.yaml [--workers N] [--backend process|ray] [--out DIR] [--keep-logs]
                          [--resume] [--force] [--yes]
    cosim compare [--trackers A,B] [--scenarios X,Y] [--seeds N] [--out DIR] [--force]
                  [--resume] [--keep-logs] [--json]
    cosim export --ros2 LOG.mcap [--out BAG.mcap] [--force]
    cosim render FILE.mcap [--out VIDEO.mp4] [--fps N] [--width W] [--height H]
                           [--start S] [--duration S] [--gl osmesa|egl|glfw]
    cosim config show SCENARIO [--config FILE.yaml] [--set key.path=value ...] [...]
    cosim config keys [PREFIX]
    cosim --version

The options and exit codes are a stable interface: scripts and outside tests rely on them.

Exit codes of ``cosim run``: 0 when the run's outcome is ``ok`` (and no --fail-if holds);
2 on bad input (one line on stderr naming the bad value and what was expected); 3 when the
run ended badly (its ``outcome`` is ``spun``, ``rolled_over``, ``off_road``,
``end_of_path``, ``diverged`` ...: see cosim.simulation.outcome) or a --fail-if condition
holds (the log is complete up to the end or the abort in both cases); 130 on an interrupt;
1 when a file cannot be written (a full disk) or a standard stream is closed.
A sweep exits 0 when every run has a row (failed runs and failed pass criteria included: the
results say so), 1 if a worker process died, 130 on an interrupt (finish with --resume).
"""

from __future__ import annotations

import argparse
import contextlib
import datetime
import json
import math
import os
import sys
import warnings
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any, NoReturn

from cosim.core.exceptions import CosimError

EXIT_USAGE = 2
EXIT_IO = 1
EXIT_BAD_OUTCOME = 3
EXIT_INTERRUPT = 130


class _Parser(argparse.ArgumentParser):
    """argparse, but a usage error is one line (not usage + error) and exit code 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message}\n")


def _build_parser() -> argparse.ArgumentParser:
    from cosim import __version__, config_cli

    parser = _Parser(
        prog="cosim", formatter_class=argparse.RawDescriptionHelpFormatter,
        description=__doc__.split("\n\n")[1],
        epilog="Every command has its own --help. Configuration keys and their units: "
        "`cosim config keys`; what a run would use: `cosim config show SCENARIO`.")
    parser.add_argument("--version", action="version", version=f"cosim {__version__}")
    commands = parser.add_subparsers(dest="command", required=True, parser_class=_Parser,
                                     metavar="COMMAND")

    run = commands.add_parser("run", help="run a scenario and log it to MCAP")
    run.add_argument("scenario", help="built-in scenario name (see `cosim scenarios`) or YAML")
    run.add_argument("--config", metavar="FILE.yaml", help="YAML merged over the scenario")
    run.add_argument("--tracker", metavar="NAME",
                     help="path tracker: dynamic-nmpc (default), kinematic-nmpc, ltv-mpc, "
                     "dynamic-mpc, open-loop ... (`cosim trackers`), an installed plug-in, "
                     "my_pkg.my_module:MyTracker or a co-simulation FMU, fmu:PATH.fmu")
    run.add_argument("--estimator", metavar="NAME",
                     help="state estimator: ekf (default), ukf, truth (debugging)")
    run.add_argument("--seed", type=int, metavar="N", help="seed of every noise source")
    run.add_argument("--duration", type=float, metavar="S",
                     help="simulated seconds (sim.duration_s)")
    run.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                     dest="overrides", help="override a config key, e.g. tracker.horizon=30 "
                     "(repeatable; every key, its unit and range: `cosim config keys`)")
    run.add_argument("--out", metavar="FILE.mcap",
                     help="log file (default logs/<scenario>[-<overrides>]-<time>.mcap)")
    run.add_argument("--force", action="store_true",
                     help="replace --out if it exists (refused otherwise)")
    run.add_argument("--fail-if", action="append", default=[], metavar="'METRIC>VALUE'",
                     dest="fail_if", help="exit 3 when this holds for the run's metrics "
                     "(<, <=, >, >=, ==, !=; repeatable), e.g. 'cte_max_m>0.3'")
    run.add_argument("--json", action="store_true", help="print the metrics as JSON")
    run.add_argument("--live", action="store_true",
                     help="stream the run to Foxglove while it happens (a WebSocket server)")
    run.add_argument("--port", type=int, metavar="N",
                     help="with --live: the port to serve on (8765; 0: any free port)")
    run.add_argument("--host", metavar="ADDRESS",
                     help="with --live: the address to listen on (127.0.0.1: this machine "
                          "only; 0.0.0.0 serves every network the machine is on)")
    run.add_argument("--pace", type=float, metavar="RATE",
                     help="with --live: hold the run at RATE times real time (1: real time; "
                          "0 or none: as fast as it goes)")
    run.add_argument("--video", metavar="FILE.mp4",
                     help="also render the run to this video (see `cosim render`)")

    inspect = commands.add_parser("inspect", help="summarise an MCAP log")
    inspect.add_argument("file", metavar="FILE.mcap")
    inspect.add_argument("--json", action="store_true", help="print one JSON object")
    inspect.add_argument("--topic", metavar="T", help="print this topic's messages (JSON lines)")
    inspect.add_argument("--head", type=int, metavar="N", help="only the first N messages")
    inspect.add_argument("--csv", metavar="DIR",
                         help="write each topic (or only --topic) as DIR/<topic>.csv")

    plot = commands.add_parser("plot", help="PNG figures of a log (or two logs overlaid)")
    plot.add_argument("files", metavar="FILE.mcap", nargs="+",
                      help="a log, or several (up to 6) to overlay")
    plot.add_argument("--out", metavar="DIR",
                      help="output directory (default <log>-plots beside the log)")

    export = commands.add_parser(
        "export", help="a log in another format: --ros2, an MCAP of ROS 2 messages")
    export.add_argument("--ros2", metavar="LOG.mcap", required=True,
                        help="the run log to export as standard ROS 2 messages (nav_msgs, "
                        "sensor_msgs, tf2_msgs, ackermann_msgs; CDR) for ros2 bag play")
    export.add_argument("--out", metavar="BAG.mcap",
                        help="the MCAP to write (default <log>-ros2.mcap beside the log)")
    export.add_argument("--force", action="store_true",
                        help="replace --out if it exists (refused otherwise)")

    commands.add_parser("scenarios", help="list the built-in scenarios")
    commands.add_parser("trackers", help="list the trackers: built in and installed plug-ins")
    commands.add_parser("estimators",
                        help="list the estimators: built in and installed plug-ins")
    compare = commands.add_parser(
        "compare", help="every tracker on every scenario and seed: a league table")
    compare.add_argument("--trackers", metavar="A,B,..",
                         help="trackers to compare (default: every closed-loop tracker)")
    compare.add_argument("--scenarios", metavar="X,Y,..",
                         help="scenarios, built-in names or YAML paths (default: the library)")
    compare.add_argument("--seeds", type=int, default=1, metavar="N",
                         help="seeds 0..N-1 per combination (default 1)")
    compare.add_argument("--workers", type=int, metavar="N",
                         help="parallel runs (default: the usable cores)")
    compare.add_argument("--duration", type=float, metavar="S",
                         help="override every scenario's sim.duration_s")
    compare.add_argument("--json", action="store_true",
                         help="print every run as {scenario, tracker, seed, metrics}")
    compare.add_argument("--live", action="store_true", help=argparse.SUPPRESS)
    compare.add_argument("--out", metavar="DIR",
                         help="write league.md, league.csv, league.png, rows.json "
                         "(default logs/compare-<time>)")
    compare.add_argument("--keep-logs", action="store_true",
                         help="keep every run's MCAP log in DIR/logs")
    compare.add_argument("--force", action="store_true",
                         help="write into a --out DIR that has files (refused otherwise)")
    compare.add_argument("--resume", action="store_true",
                         help="finish the interrupted comparison in --out DIR (same options)")

    identify = commands.add_parser(
        "identify", help="identify the plant's bicycle-model parameters and actuator lags")
    identify.add_argument("--config", metavar="FILE.yaml",
                          help="YAML merged over the lane-change scenario")
    identify.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                          dest="overrides", help="override a config key, e.g. plant.mass_kg=2000")
    identify.add_argument("--json", action="store_true", help="print one JSON object")

    sweep = commands.add_parser(
        "sweep", help="run a scenario over a grid or random sample of parameters and seeds")
    sweep.add_argument("spec", metavar="SPEC.yaml", help="the sweep spec (see cosim.sweeps.spec)")
    sweep.add_argument("--workers", type=int, metavar="N",
                       help="parallel runs (default: the number of cores)")
    sweep.add_argument("--backend", choices=("process", "ray"), default="process",
                       help="process pool on this machine (default) or Ray")
    sweep.add_argument("--live", action="store_true", help=argparse.SUPPRESS)
    sweep.add_argument("--out", metavar="DIR",
                       help="output directory (default logs/sweep-<spec>-<time>)")
    sweep.add_argument("--keep-logs", action="store_true",
                       help="keep every run's MCAP log under DIR/logs")
    sweep.add_argument("--resume", action="store_true",
                       help="finish the interrupted sweep in --out DIR (same spec)")
    sweep.add_argument("--force", action="store_true",
                       help="start the sweep afresh in a --out DIR that has files")
    sweep.add_argument("--yes", action="store_true",
                       help="run a sweep of more than 10 000 runs (refused otherwise)")

    render = commands.add_parser(
        "render", help="render a log to a video from a chase camera (MuJoCo, offscreen)")
    render.add_argument("file", metavar="FILE.mcap")
    render.add_argument("--out", metavar="VIDEO.mp4",
                        help="video file (default: beside the log, logs/x.mcap -> logs/x.mp4)")
    render.add_argument("--fps", type=float, default=30.0, metavar="N",
                        help="frames per second (default 30)")
    render.add_argument("--width", type=int, default=640, metavar="W", help="pixels (640)")
    render.add_argument("--height", type=int, default=360, metavar="H", help="pixels (360)")
    render.add_argument("--start", type=float, default=0.0, metavar="S",
                        help="first frame at S seconds into the log")
    render.add_argument("--duration", type=float, metavar="S", help="seconds of video")
    render.add_argument("--gl", choices=("osmesa", "egl", "glfw"),
                        help="OpenGL back-end (default MUJOCO_GL, else osmesa: software)")
    config_cli.add_parser(commands, _Parser)
    return parser


def _format_value(value: Any) -> str:
    if isinstance(value, bool) or value is None:
        return {True: "true", False: "false", None: "n/a"}[value]
    if isinstance(value, float):
        return "n/a" if not math.isfinite(value) else f"{value:.4g}"
    return str(value)


def _print_table(title: str, rows: list[tuple[str, str]]) -> None:
    if sys.stdout.isatty():
        from rich.console import Console
        from rich.table import Table

        table = Table(title=title)
        table.add_column("metric")
        table.add_column("value", justify="right")
        for key, value in rows:
            table.add_row(key, value)
        Console().print(table)
        return
    width = max(len(key) for key, _ in rows)
    print(title)
    for key, value in rows:
        print(f"  {key:<{width}}  {value}")


def _json_ready(values: dict[str, Any]) -> dict[str, Any]:
    return {k: (None if isinstance(v, float) and not math.isfinite(v) else v)
            for k, v in values.items()}


def _command_run(args: argparse.Namespace) -> int:
    from cosim.simulation.fail_if import parse_conditions
    from cosim.simulation.runner import run
    from cosim.simulation.scenario_config import load_config

    conditions = parse_conditions(args.fail_if)
    live = _live_options(args)
    if args.video is not None:
        from cosim.plots.render import check_video_path

        check_video_path(args.video, "--video")
    if args.duration is not None and not (math.isfinite(args.duration) and args.duration >= 0):
        raise CosimError(f"--duration {args.duration}: expected a number of seconds >= 0")
    config = load_config(args.scenario, args.config, args.overrides, args.seed,
                         args.duration, args.tracker, args.estimator)
    with contextlib.ExitStack() as stack:
        out = stack.enter_context(_claim_out(args, config.name))
        mirror = None
        if live is not None:
            from cosim.log.live import LiveStream

            mirror = stack.enter_context(LiveStream(live))
            paced = f"paced at {live.pace:g}x real time" if live.pace else "not paced"
            print(f"cosim: live at {mirror.url} ({paced}); in Foxglove: Open connection > "
                  "Foxglove WebSocket", file=sys.stderr, flush=True)
        if sys.stderr.isatty():
            from rich.progress import Progress

            with Progress(transient=True) as bar:
                task = bar.add_task(f"{config.name}", total=1.0)
                result = run(config, out, lambda done: bar.update(task, completed=done),
                             mirror=mirror)
        else:
            result = run(config, out, mirror=mirror)
    shown = _shown_metrics(result.metrics, config.tracker.name == "open-loop")
    if args.json:
        print(json.dumps({"log": str(result.log_path), "metrics": _json_ready(result.metrics)}))
    else:
        _print_table(f"{config.name} (seed {config.seed}) -> {result.log_path}",
                     [(k, _format_value(v)) for k, v in shown.items()])
    if result.abort_reason == "interrupted":
        print(f"cosim: interrupted; log written up to the interrupt: {result.log_path}",
              file=sys.stderr)
        return EXIT_INTERRUPT
    if args.video is not None:
        from cosim.plots.render import RenderOptions, describe, render_for_cli

        print(describe(render_for_cli(result.log_path, args.video, RenderOptions())),
              file=sys.stderr if args.json else sys.stdout)
    outcome = str(result.metrics.get("outcome", "ok"))
    when = result.metrics.get(f"{outcome}_t_s")
    if isinstance(when, float):  # an event: it is on /events
        stopped = "" if result.completed else \
            "; the run stopped there (--set outcome.keep_going=true runs on)"
        print(f"cosim: run ended badly: outcome {outcome} at t = {when:.2f} s{stopped} "
              f"(see /events in {result.log_path})", file=sys.stderr)
        return EXIT_BAD_OUTCOME
    if not result.completed:
        print(f"cosim: run aborted ({outcome}): {result.abort_reason}; "
              f"log: {result.log_path}", file=sys.stderr)
        return EXIT_BAD_OUTCOME
    held = [c for c in conditions if c.holds(result.metrics)]
    if held:
        missing = "" if held[0].metric in result.metrics else \
            f" (this run has no metric {held[0].metric!r})"
        print(f"cosim: --fail-if {held[0].text!r} holds{missing}"
              + (f" (and {len(held) - 1} more)" if len(held) > 1 else ""), file=sys.stderr)
        return EXIT_BAD_OUTCOME
    return 0


@contextlib.contextmanager
def _claim_out(args: argparse.Namespace, scenario: str) -> Iterator[Path]:
    """The run's log name, held for this run (:func:`cosim.log.output_claim.claim_output`):
    ``--out`` as given (refused when another run holds it), else the default name, with
    ``-2``, ``-3`` ... when a run started in the same second holds that."""
    from cosim.log.output_claim import OutputTakenError, claim_output

    inputs = (args.config, args.scenario, args.video)
    if args.out is not None:
        with claim_output(Path(args.out), "--out", args.force, inputs) as out:
            yield out
        return
    from cosim.log.names import default_log_name, override_tag
    from cosim.simulation.changes import file_changes

    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    tag = override_tag([*file_changes(args.scenario, args.config), *args.overrides],
                       args.tracker, args.estimator, args.seed, args.duration, args.config)
    default = Path("logs") / default_log_name(scenario, tag, stamp)
    for attempt in range(1, 100):
        name = default if attempt == 1 else \
            default.with_name(f"{default.stem}-{attempt}{default.suffix}")
        with contextlib.ExitStack() as stack:
            try:
                out = stack.enter_context(claim_output(name, "--out", False, inputs))
            except OutputTakenError:
                continue
            except CosimError:
                if name.exists():  # made by a run of the same second that has ended
                    continue
                raise
            yield out
            return
    raise CosimError(f"--out: every name like {str(default)!r} is taken: expected --out")


def _live_options(args: argparse.Namespace) -> Any:
    """``--live`` and its settings as :class:`cosim.log.live.LiveOptions`, or None; a live
    setting without ``--live`` is refused (it would be ignored)."""
    given = [f"--{name} {value}" for name, value in
             (("port", args.port), ("host", args.host), ("pace", args.pace)) if value is not None]
    if not args.live:
        if given:
            raise CosimError(f"{given[0]}: only meaningful with --live; expected --live too "
                             "(or drop it)")
        return None
    from cosim.log.live import DEFAULT_PORT, LiveOptions

    return LiveOptions(host=args.host if args.host is not None else "127.0.0.1",
                       port=args.port if args.port is not None else DEFAULT_PORT,
                       pace=args.pace if args.pace is not None else 0.0)


def _refuse_live(args: argparse.Namespace, command: str) -> None:
    if args.live:
        raise CosimError(f"cosim {command} --live: only a single run streams; expected "
                         "`cosim run SCENARIO --live` for the case you want to watch")


PATH_TRACKING_METRICS = ("cte_max_m", "cte_rms_m", "heading_err_max_rad",
                         "heading_err_rms_rad", "speed_err_rms_mps")
"""Not shown in an open-loop run's table: it follows no path (they stay in the log)."""


def _shown_metrics(metrics: dict[str, Any], open_loop: bool) -> dict[str, Any]:
    """The metrics a run prints: the outcome first; an open-loop run's manoeuvre figures
    instead of path-tracking errors."""
    shown = {"outcome": metrics.get("outcome", "ok"), **metrics}
    if open_loop:
        shown = {k: v for k, v in shown.items() if k not in PATH_TRACKING_METRICS}
    return shown


def _command_inspect(args: argparse.Namespace) -> int:
    from cosim.log.export import csv_command, log_warnings
    from cosim.log.reader import iter_messages, read_summary
    from cosim.simulation.changes import base_scenario, changes_text, config_changes

    path = Path(args.file)
    if not path.is_file():
        raise CosimError(f"{args.file!r}: no such file (expected an MCAP log)")
    summary = read_summary(path)
    if args.csv is not None:
        return csv_command(summary, args.csv, args.topic, args.head)
    if args.topic is not None:
        topics = [c.topic for c in summary.channels]
        if args.topic not in topics:
            raise CosimError(f"--topic {args.topic!r}: expected one of "
                             f"{', '.join(topics) or '(none: the log has no channels)'}")
        if args.head is not None and args.head < 0:
            raise CosimError(f"--head {args.head}: expected a count >= 0")
        for n, (log_time_ns, message) in enumerate(iter_messages(path, args.topic)):
            if args.head is not None and n >= args.head:
                break
            print(json.dumps({"log_time_ns": log_time_ns, **message}))
        return 0
    document = {
        "file": str(path),
        "truncated": summary.truncated,
        "duration_s": summary.duration_s,
        "message_count": summary.message_count,
        "channels": [
            {"topic": c.topic, "schema": c.schema_name, "schema_encoding": c.schema_encoding,
             "message_encoding": c.message_encoding, "count": c.message_count}
            for c in sorted(summary.channels, key=lambda c: c.topic)
        ],
        "attachments": summary.attachments,
        "versions": summary.versions,
        "config": summary.config,
        "changes": config_changes(summary.config) if summary.config else [],
        "metrics": summary.metrics or {},
        "warnings": log_warnings(summary),
    }
    if args.json:
        print(json.dumps(document))
        return 0
    print(f"{path}  {summary.duration_s:.3f} s  {summary.message_count} messages"
          + ("  (TRUNCATED: read up to the last complete record)" if summary.truncated else ""))
    if summary.metrics:
        print(f"outcome {summary.metrics.get('outcome', 'n/a (logged before outcomes)')}  "
              f"completed {_format_value(summary.metrics.get('completed'))}")
    width = max((len(c["topic"]) for c in document["channels"]), default=0)
    for channel in document["channels"]:
        print(f"  {channel['topic']:<{width}}  {channel['count']:>7}  {channel['schema']}")
    config = summary.config
    if config:
        print(f"scenario {config.get('name')}  seed {config.get('seed')}  tracker "
              f"{config.get('tracker', {}).get('name')}  estimator "
              f"{config.get('estimator', {}).get('name')}")
        print(f"changed from {base_scenario(config)}: "
              f"{changes_text(document['changes'], at_most=12)}")
    if summary.versions:
        print("versions " + "  ".join(f"{k} {v}" for k, v in summary.versions.items()))
    for warning in document["warnings"]:
        print(f"WARNING: {warning}")
    if summary.metrics:
        _print_table("metrics", [(k, _format_value(v)) for k, v in summary.metrics.items()])
    elif summary.written_by_cosim:
        print("metrics: none (the run did not finish)")
    return 0


def _command_plot(args: argparse.Namespace) -> int:
    from cosim.plots import plot_command

    return plot_command(args.files, args.out)


def _command_scenarios(args: argparse.Namespace) -> int:
    from cosim.simulation.scenario_config import builtin_scenarios

    del args
    for name, description in builtin_scenarios().items():
        print(f"{name:<20} {description}")
    return 0


def _command_trackers(args: argparse.Namespace) -> int:
    from cosim.core.plugins import entry_point_names
    from tracker.config import PLUGIN_GROUP
    from tracker.registry import TRACKER_NAMES

    del args
    return _print_components(TRACKER_NAMES, entry_point_names(PLUGIN_GROUP), PLUGIN_GROUP,
                             "--tracker")


def _command_estimators(args: argparse.Namespace) -> int:
    from cosim.core.plugins import entry_point_names
    from estimation.config import ESTIMATOR_NAMES, PLUGIN_GROUP

    del args
    return _print_components(ESTIMATOR_NAMES, entry_point_names(PLUGIN_GROUP), PLUGIN_GROUP,
                             "--estimator")


def _print_components(builtin: Sequence[str], plugins: dict[str, str], group: str,
                      option: str) -> int:
    """Built-in names, then the installed plug-ins of ``group`` with the class each names."""
    width = max(len(name) for name in [*builtin, *plugins])
    for name in builtin:
        print(f"{name:<{width}}  built in")
    for name, target in plugins.items():
        print(f"{name:<{width}}  plug-in {target}")
    if not plugins:
        print(f"(no plug-ins installed: entry point group {group!r}; or use {option} "
              "my_pkg.my_module:MyClass)")
    return 0


IDENTIFY_SCENARIO = "lane-change"
"""`cosim identify` identifies the plant of this scenario's config (with the overrides)."""


def _command_identify(args: argparse.Namespace) -> int:
    from cosim.identification import identify
    from cosim.simulation.scenario_config import load_config

    config = load_config(IDENTIFY_SCENARIO, args.config, args.overrides)
    model = identify(config.plant, config.tracker.model, config.sim.physics_dt_s)
    if args.json:
        print(json.dumps(_json_ready(model.to_dict())))
        return 0
    rows = [(quantity, _format_value(value), unit, residual)
            for quantity, value, unit, residual in model.table_rows()]
    title = f"identified plant of {config.name}"
    header = ("quantity", "value", "unit", "residual")
    if sys.stdout.isatty():
        from rich.console import Console
        from rich.table import Table

        table = Table(title=title)
        for name in header:
            table.add_column(name, justify="right" if name == "value" else "left")
        for row in rows:
            table.add_row(*row)
        Console().print(table)
        return 0
    widths = [max(len(row[i]) for row in [header, *rows]) for i in range(3)]
    print(title)
    for row in [header, *rows]:
        cells = [f"{cell:<{width}}" for cell, width in zip(row[:3], widths, strict=True)]
        print(("  " + "  ".join([*cells, row[3]])).rstrip())
    return 0


def _command_sweep(args: argparse.Namespace) -> int:
    _refuse_live(args, "sweep")
    from cosim.sweeps.driver import check_sweep_dir, default_out_dir, run_sweep
    from cosim.sweeps.execute import WorkerCrashError

    if args.resume and args.out is None:
        raise CosimError("--resume: expected --out DIR, the directory of the sweep to finish")
    if not Path(args.spec).is_file():
        raise CosimError(f"{args.spec!r}: no such file (expected a sweep spec YAML)")
    out = Path(args.out) if args.out is not None else default_out_dir(Path(args.spec))
    check_sweep_dir(out, args.force, args.resume)
    resume_hint = f"resume with `cosim sweep {args.spec} --out {out} --resume`"
    try:
        outcome = run_sweep(args.spec, out, args.workers, args.backend, args.keep_logs,
                            args.resume, yes=args.yes, force=args.force)
    except WorkerCrashError as error:
        print(f"cosim: sweep aborted: {error}", file=sys.stderr)
        return EXIT_IO
    except KeyboardInterrupt:
        print(f"cosim: sweep interrupted; finished rows are kept: {resume_hint}",
              file=sys.stderr)
        return EXIT_INTERRUPT
    except OSError as error:  # a full disk while a row or a table was written
        where = repr(error.filename) if error.filename else "the sweep's files"
        print(f"cosim: error: cannot write {where}: {error.strerror or error}; the rows "
              f"written so far are kept: {resume_hint}", file=sys.stderr)
        return EXIT_IO
    earlier = outcome.finished - outcome.ran
    print(f"sweep: {outcome.runs} runs (ran {outcome.ran} now"
          + (f", {earlier} from before" if earlier else "")
          + f") in {outcome.wall_time_s:.1f} s; {outcome.passed} pass, "
          f"{outcome.finished - outcome.passed} fail"
          + (f" ({outcome.errors} with an error)" if outcome.errors else ""))
    for path in outcome.files:
        print(f"  {path}")
    return 0


def _command_compare(args: argparse.Namespace) -> int:
    _refuse_live(args, "compare")
    import time as _time

    from cosim.sweeps import compare
    from cosim.sweeps.driver import sigterm_as_interrupt
    from tracker.config import is_plugin_name
    from tracker.fmu.config import is_fmu_name
    from tracker.registry import TRACKER_NAMES

    closed_loop = [name for name in TRACKER_NAMES if name != "open-loop"]
    trackers = compare.parse_names(args.trackers, compare.DEFAULT_TRACKERS, None, "trackers")
    for name in trackers:  # built-in closed-loop trackers, or trackers from outside cosim
        if name not in closed_loop and not is_plugin_name(name) and not is_fmu_name(name):
            raise CosimError(f"--trackers: {name!r} is not one of {', '.join(closed_loop)}, "
                             "an installed plug-in, module:Class or fmu:PATH.fmu")
    scenarios = compare.parse_names(args.scenarios, compare.DEFAULT_SCENARIOS, None,
                                    "scenarios")
    if args.workers is not None and args.workers < 1:
        raise CosimError(f"--workers {args.workers}: expected at least 1")
    if args.resume and args.out is None:
        raise CosimError("--resume: expected --out DIR, the folder of the comparison to finish")
    out = Path(args.out) if args.out else Path("logs") / _time.strftime("compare-%Y%m%d-%H%M%S")
    try:
        with sigterm_as_interrupt():
            rows = compare.run_compare(scenarios, trackers, args.seeds, args.workers,
                                       args.duration, out, args.keep_logs, args.force,
                                       args.resume)
    except compare.CompareInterrupted as stop:  # Ctrl-C or SIGTERM: finished runs kept
        league = ""
        if stop.rows:
            compare.write_outputs(stop.rows, out)
            league = f"the league of the {len(stop.rows)} finished run(s) is in " \
                f"{out / 'league.md'}; "
        print(f"cosim: compare interrupted; {league}finish with --resume --out {out}",
              file=sys.stderr)
        return EXIT_INTERRUPT
    table = compare.write_outputs(rows, out)
    if args.json:
        print(json.dumps(compare.json_rows(rows), indent=1))
        return 0
    _print_league(table)
    for name in ("league.md", "league.csv", "league.png", "rows.json"):
        print(f"  {out / name}")
    return 0


def _print_league(table: list[Any]) -> None:
    """The league, in the terminal's width (unlimited when piped: every number whole)."""
    import shutil

    from cosim.sweeps.compare import league_text

    width = shutil.get_terminal_size().columns if sys.stdout.isatty() else None
    print(league_text(table, width))


def _command_export(args: argparse.Namespace) -> int:
    from cosim.log.ros2 import require_rosbags

    require_rosbags()
    from cosim.log.ros2.bag import export_ros2

    result = export_ros2(args.ros2, args.out, args.force)
    if result.truncated:
        print(f"cosim: warning: {args.ros2!r} was cut off: exported up to its last complete "
              "record", file=sys.stderr)
    print(f"{sum(result.message_counts.values())} ROS 2 messages -> {result.path}")
    for topic, count in result.message_counts.items():
        print(f"  {topic:<20} {count}")
    print(f"replay: ros2 bag play -s mcap {result.path} --clock  (nodes with "
          "use_sim_time:=true; the stamps are simulated time from sim.epoch)")
    return 0


def _command_render(args: argparse.Namespace) -> int:
    from cosim.plots.render import RenderOptions, describe, render_for_cli

    options = RenderOptions(args.fps, args.width, args.height, args.start, args.duration,
                            args.gl)
    print(describe(render_for_cli(args.file, args.out, options)))
    return 0


def _command_config(args: argparse.Namespace) -> int:
    from cosim import config_cli

    return config_cli.command(args)
def _one_line_warning(message: Warning | str, category: type[Warning], filename: str,
                      lineno: int, file: Any = None, line: str | None = None) -> None:
    """A warning as one line on stderr (``cosim: warning: ...``), without source lines."""
    print(f"cosim: warning: {message}", file=sys.stderr)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``cosim`` console script."""
    args = _build_parser().parse_args(argv)
    handlers = {"run": _command_run, "inspect": _command_inspect, "plot": _command_plot,
                "scenarios": _command_scenarios, "identify": _command_identify,
                "sweep": _command_sweep, "render": _command_render,
                "config": _command_config, "compare": _command_compare,
                "export": _command_export,
                "trackers": _command_trackers, "estimators": _command_estimators}
    try:
        with warnings.catch_warnings():
            warnings.showwarning = _one_line_warning
            code = handlers[args.command](args)
        sys.stdout.flush()  # a full or closed stdout fails here, not at exit
        return code
    except CosimError as error:
        _say(f"cosim: error: {error}")
        return EXIT_USAGE
    except KeyboardInterrupt:  # before or after a run's loop (the loop handles its own)
        _say("cosim: interrupted")
        return EXIT_INTERRUPT
    except BrokenPipeError:  # `cosim ... | head`: the reader has what it wanted
        _silence_stdout()
        return 0
    except OSError as error:  # a full disk, a full stdout
        _silence_stdout()
        where = f"{error.filename!r}" if error.filename else "a file or standard output"
        _say(f"cosim: error: cannot write {where}: {error.strerror or error}")
        return EXIT_IO


def _say(line: str) -> None:
    """One line on stderr, even when stderr itself is gone."""
    with contextlib.suppress(OSError):
        print(line, file=sys.stderr, flush=True)


def _silence_stdout() -> None:
    """Point stdout at /dev/null so that Python's exit does not fail flushing it again."""
    with contextlib.suppress(OSError, ValueError):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())


if __name__ == "__main__":
    sys.exit(main())
