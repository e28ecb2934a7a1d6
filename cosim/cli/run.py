"""``cosim run``: run a scenario, log it to MCAP, print its metrics, exit by its outcome."""

from __future__ import annotations

import argparse
import contextlib
import datetime
import json
import math
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from cosim.cli.common import (
    EXIT_BAD_OUTCOME,
    EXIT_INTERRUPT,
    Handler,
    format_value,
    json_ready,
    print_table,
)
from cosim.core.exceptions import CosimError

PATH_TRACKING_METRICS = ("cte_max_m", "cte_rms_m", "heading_err_max_rad",
                         "heading_err_rms_rad", "speed_err_rms_mps")
"""Not shown in an open-loop run's table: it follows no path (they stay in the log)."""

HEADLINE_METRICS = ("outcome", "completed", "cte_max_m", "cte_rms_m", "heading_err_max_rad",
                    "speed_err_rms_mps", "est_pos_rmse_m", "nees_mean", "solver_failures",
                    "step_ms_p50", "realtime_factor", "gates_hit", "track_limit_exceedances",
                    "lap_time_s", "gap_min_m", "ttc_min_s", "stl_robustness")
"""What ``cosim run`` prints by default (the keys a run has), then any event's time and
any warning count that is not zero; ``--all`` prints every metric."""

NOTICES = ("belief_mismatches", "filter_warnings", "events")
"""Counts shown in the headline when they are not zero."""


def add_parsers(commands: Any) -> dict[str, Handler]:
    run = commands.add_parser("run", help="run a scenario and log it to MCAP")
    run.add_argument("scenario", help="built-in scenario name (see `cosim scenarios`) or YAML")
    run.add_argument("--config", metavar="FILE.yaml", action="append",
                     help="YAML merged over the scenario; repeat to merge several in order "
                          "(a later file wins a key both set)")
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
                     "(<, <=, >, >=, ==, !=; repeatable), e.g. 'cte_max_m>0.3', or when this "
                     "STL formula holds, e.g. 'eventually (abs(cte_m) > 0.3)'")
    run.add_argument("--require", action="append", default=[], metavar="'STL FORMULA'",
                     help="exit 3 when the run violates this STL requirement over its "
                     "signals (repeatable; cosim.simulation.requirements), e.g. "
                     "'always (abs(cte_m) <= 0.3)'; its robustness is the metric "
                     "stl_robustness_<i>")
    run.add_argument("--json", action="store_true", help="print the metrics as JSON")
    run.add_argument("--all", action="store_true",
                     help="print every metric (default: the headline ones)")
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
    return {"run": command}


def command(args: argparse.Namespace) -> int:
    from cosim.simulation.fail_if import bind_formulas, formula_requirements, parse_conditions
    from cosim.simulation.requirements import with_requirements
    from cosim.simulation.scenario_config import load_config

    conditions = parse_conditions(args.fail_if)
    live = _live_options(args)
    if args.video is not None:
        from cosim.plots.render import check_video_path

        check_video_path(args.video, "--video")
    if args.duration is not None and not (math.isfinite(args.duration) and args.duration > 0):
        raise CosimError(f"--duration {args.duration}: expected a number of seconds > 0")
    config = load_config(args.scenario, args.config, args.overrides, args.seed,
                         args.duration, args.tracker, args.estimator)
    config, first = with_requirements(config, formula_requirements(conditions, args.require),
                                      "--require")
    conditions = bind_formulas(conditions, args.require, first)
    reporter = getattr(args, "reporter", None)
    if reporter is not None:
        reporter.tracker(config.tracker.name)
    with _claim_out(args, config.name) as out:
        if reporter is not None:
            reporter.log(out)
        return _run_and_report(args, config, out, live, conditions, reporter)


def _run_and_report(args: argparse.Namespace, config: Any, out: Path, live: Any,
                    conditions: list[Any], reporter: Any) -> int:
    """Run ``config`` to ``out``, print its metrics and return the exit code (in the
    guarded child, ``reporter`` tells the parent how far the run is)."""
    from cosim.simulation.runner import run

    duration_s = config.sim.duration_s
    # In the guarded child the parent writes the log (cosim.log.piped_recorder).
    log_link = getattr(reporter, "log_link", None)

    def reached(done: float) -> None:
        if reporter is not None:
            if done == 0.0:
                reporter.ready()
            reporter.reached(done * duration_s)

    with contextlib.ExitStack() as stack:
        stream = None
        if live is not None:
            from cosim.log.live import LiveStream

            stream = stack.enter_context(LiveStream(live))
            paced = f"paced at {live.pace:g}x real time" if live.pace else "not paced"
            print(f"cosim: live at {stream.url} ({paced}); in Foxglove: Open connection > "
                  "Foxglove WebSocket", file=sys.stderr, flush=True)
        try:
            if sys.stderr.isatty():
                from rich.progress import Progress

                with Progress(transient=True) as bar:
                    task = bar.add_task(f"{config.name}", total=1.0)

                    def shown(done: float) -> None:
                        bar.update(task, completed=done)
                        reached(done)

                    result = run(config, out, shown, live=stream, log_link=log_link)
            else:
                result = run(config, out, reached, live=stream, log_link=log_link)
        except CosimError as error:  # refused during the run: say where its log is
            if Path(out).is_file():
                raise type(error)(f"{error} (the log up to it: {out})") from None
            raise
    shown_now = shown_metrics(result.metrics, config.tracker.name == "open-loop", args.all)
    if args.json:
        print(json.dumps({"log": str(result.log_path), "metrics": json_ready(result.metrics)}))
    else:
        print_table(f"{config.name} ({_seeds(config)}) -> {result.log_path}",
                    [(k, format_value(v)) for k, v in shown_now.items()])
        hidden = len(result.metrics) - len(shown_now)
        if hidden > 0:
            print(f"  ({hidden} more metrics: --all, or cosim inspect {result.log_path})")
    if result.abort_reason == "interrupted":
        print(f"cosim: interrupted; log written up to the interrupt: {result.log_path}",
              file=sys.stderr)
        return EXIT_INTERRUPT
    if args.video is not None:
        from cosim.plots.render import RenderOptions, describe, render_for_cli

        print(describe(render_for_cli(result.log_path, args.video, RenderOptions())),
              file=sys.stderr if args.json else sys.stdout)
    return _exit_code(result, conditions)


def died(args: argparse.Namespace, death: Any) -> int:
    """Say how the guarded run's process (:mod:`cosim.cli.guard`) ended without finishing,
    which component is the likely cause and what is left of the log; exit 3 (130 for an
    interrupt that came before the run's own handler)."""
    out = None if death.log_path is None else Path(death.log_path)
    if out is not None:
        from cosim.log.output_claim import lock_path
        from cosim.log.safe_file import partial_path

        partial_path(out).unlink(missing_ok=True)  # died before the log took its name
        lock_path(out).unlink(missing_ok=True)  # its holder is gone: the claim with it
    if death.interrupted:
        print(f"cosim: interrupted ({death.how}); {_what_is_left(out)}", file=sys.stderr)
        return EXIT_INTERRUPT
    when = "during set-up" if death.last_t_s is None else \
        f"after t = {death.last_t_s:.2f} s of the run"
    reason = f"the run's process died {when} ({death.how}, without a word)"
    cause = _likely_cause(death.tracker)
    print(f"cosim: error: {reason}: {cause}; {_what_is_left(out)}", file=sys.stderr)
    if args.json:
        print(json.dumps({"log": str(out) if out is not None and out.is_file() else None,
                          "metrics": {"outcome": "error", "completed": False,
                                      "abort_reason": f"{reason}: {cause}"}}))
    return EXIT_BAD_OUTCOME


def _likely_cause(name: str | None) -> str:
    from tracker.config import is_plugin_name
    from tracker.fmu.config import is_fmu_name

    if name is None:
        return "it died before its configuration was read"
    if is_fmu_name(name):
        return (f"the tracker {name!r} is an FMU whose own code runs in the run's process, "
                "the likely cause")
    if is_plugin_name(name):
        return (f"the tracker {name!r} is a plug-in whose own code runs in the run's process, "
                "the likely cause")
    return ("no foreign component in this run: native code of the simulation (MuJoCo, "
            "CasADi, the compiled pieces) failed or the process was killed")


def _what_is_left(out: Path | None) -> str:
    if out is None or not out.is_file():
        return "no log was written (the run had not started)"
    from cosim.log.reader import read_summary

    try:
        summary = read_summary(out)
    except Exception:  # noqa: BLE001 - any unreadable log gets the same answer
        return f"the log {str(out)!r} holds nothing readable"
    # The parent writes the log of a guarded run: it finishes it with what the run sent.
    kept = "its last complete chunk" if summary.truncated else "every message the run sent"
    return (f"the log up to t = {summary.duration_s:.2f} s ({kept}) is in {out} "
            "(cosim inspect reads it)")


def _seeds(config: Any) -> str:
    """The run's seed, and the circuit's where the path is generated from one: they are two
    seeds (``--seed`` draws the noise, ``path.seed`` the circuit)."""
    circuit = f", circuit path.seed {config.path.seed}" if config.path.kind == "generated" else ""
    return f"run seed {config.seed}{circuit}"


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


@contextlib.contextmanager
def _claim_out(args: argparse.Namespace, scenario: str) -> Iterator[Path]:
    """The run's log name, held for this run (:func:`cosim.log.output_claim.claim_output`):
    ``--out`` as given (refused when another run holds it), else the default name, with
    ``-2``, ``-3`` ... when a run started in the same second holds that."""
    from cosim.log.output_claim import OutputTakenError, claim_output

    inputs = (*(args.config or ()), args.scenario, args.video)
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


def _exit_code(result: Any, conditions: list[Any]) -> int:
    """0 for a completed ``ok`` run with no ``--fail-if`` holding, else 3 with one line why.

    A run whose outcome is not ``ok`` fails every ``--fail-if`` too, whatever its metrics
    say: a run that stopped early has metrics of the part before the stop (a spun car's
    ``cte_max_m`` can look like a good run's); a second line says so."""
    outcome = str(result.metrics.get("outcome", "ok"))
    when = result.metrics.get(f"{outcome}_t_s")
    if isinstance(when, float):  # an event: it is on /events
        stopped = "" if result.completed else \
            "; the run stopped there (--set outcome.keep_going=true runs on)"
        print(f"cosim: run ended badly: outcome {outcome} at t = {when:.2f} s{stopped} "
              f"(see /events in {result.log_path})", file=sys.stderr)
        _fails_every_condition(conditions, f"outcome {outcome} at t = {when:.2f} s",
                               result.completed)
        return EXIT_BAD_OUTCOME
    if not result.completed:
        print(f"cosim: run aborted ({outcome}): {result.abort_reason}; "
              f"log: {result.log_path}", file=sys.stderr)
        _fails_every_condition(conditions, f"outcome {outcome}", result.completed)
        return EXIT_BAD_OUTCOME
    held = [c for c in conditions if c.holds(result.metrics)]
    if held:
        print(f"cosim: {held[0].failure(result.metrics)}"
              + (f" (and {len(held) - 1} more)" if len(held) > 1 else ""), file=sys.stderr)
        return EXIT_BAD_OUTCOME
    return 0


def shown_metrics(metrics: dict[str, Any], open_loop: bool,
                  every: bool = True) -> dict[str, Any]:
    """The metrics a run prints: the outcome first; an open-loop run's manoeuvre figures
    instead of path-tracking errors; unless ``every``, the headline alone
    (:data:`HEADLINE_METRICS`, events' times, non-zero :data:`NOTICES`, requirements)."""
    shown = {"outcome": metrics.get("outcome", "ok"), **metrics}
    if open_loop:
        shown = {k: v for k, v in shown.items() if k not in PATH_TRACKING_METRICS}
        return shown  # the manoeuvre's own figures, all of them
    if every:
        return shown
    headline = {k: shown[k] for k in HEADLINE_METRICS if k in shown}
    headline.update({k: v for k, v in shown.items()
                     if (k.endswith("_t_s") and k != "sim_duration_s")
                     or k.startswith("stl_robustness_") or (k in NOTICES and v)})
    return headline


def _fails_every_condition(conditions: list[Any], outcome: str, completed: bool) -> None:
    """Say that the ``--fail-if`` conditions fail on a bad outcome, and why not judged."""
    if not conditions:
        return
    partial = "" if completed else "; its metrics cover the run up to the stop only (partial)"
    texts = ", ".join(f"{c.option} {c.text!r}" for c in conditions)
    print(f"cosim: {texts}: the run fails on its {outcome} whatever the "
          f"metrics say{partial}", file=sys.stderr)
