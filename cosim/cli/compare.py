"""``cosim compare``: every tracker on every scenario and seed, as a league table."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

from cosim.cli.common import EXIT_INTERRUPT, Handler, refuse_live
from cosim.core.exceptions import CosimError


def add_parsers(commands: Any) -> dict[str, Handler]:
    compare = commands.add_parser(
        "compare", help="every tracker on every scenario and seed: a league table")
    compare.add_argument("--trackers", metavar="A,B,..",
                         help="trackers to compare (default: every closed-loop tracker)")
    compare.add_argument("--scenarios", metavar="X,Y,..",
                         help="scenarios, built-in names or YAML paths (default: the library)")
    compare.add_argument("--seeds", type=int, metavar="N",
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
                         help="finish the interrupted comparison in --out DIR (its "
                         "trackers, scenarios, seeds and duration unless given)")
    return {"compare": command}


def command(args: argparse.Namespace) -> int:
    refuse_live(args, "compare")
    from cosim.sweeps import compare
    from cosim.sweeps.driver import sigterm_as_interrupt
    from tracker.config import is_plugin_name
    from tracker.fmu.config import is_fmu_name
    from tracker.registry import TRACKER_NAMES

    if args.resume and args.out is not None:  # what was compared, unless given again
        _take_stored_options(args, compare.stored_what(Path(args.out)))
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
    out = Path(args.out) if args.out else Path("logs") / time.strftime("compare-%Y%m%d-%H%M%S")
    try:
        with sigterm_as_interrupt():
            rows = compare.run_compare(scenarios, trackers,
                                       args.seeds if args.seeds is not None else 1, args.workers,
                                       args.duration, out, args.keep_logs, args.force,
                                       args.resume)
    except compare.CompareInterrupted as stop:  # Ctrl-C or SIGTERM: finished runs kept
        league = ""
        if stop.rows:
            compare.write_outputs(stop.rows, out)
            league = f"the league of the {len(stop.rows)} finished run(s) is in " \
                f"{out / 'league.md'}; "
        print(f"cosim: compare interrupted; {league}finish with: cosim compare --resume "
              f"--out {out}", file=sys.stderr)
        return EXIT_INTERRUPT
    table = compare.write_outputs(rows, out)
    if args.json:
        print(json.dumps(compare.json_rows(rows), indent=1))
        return 0
    _print_league(table)
    for name in ("league.md", "league.csv", "league.png", "rows.json"):
        print(f"  {out / name}")
    return 0


def _take_stored_options(args: argparse.Namespace, what: dict[str, Any] | None) -> None:
    """Fill the options ``--resume`` was not given from the interrupted comparison's own
    record (``compare.json``), so ``cosim compare --resume --out DIR`` is enough."""
    if what is None:
        return
    if args.trackers is None and what.get("trackers"):
        args.trackers = ",".join(what["trackers"])
    if args.scenarios is None and what.get("scenarios"):
        args.scenarios = ",".join(what["scenarios"])
    if args.seeds is None and isinstance(what.get("seeds"), int):
        args.seeds = what["seeds"]
    if args.duration is None and isinstance(what.get("duration_s"), (int, float)):
        args.duration = float(what["duration_s"])


def _print_league(table: list[Any]) -> None:
    """The league, in the terminal's width (unlimited when piped: every number whole)."""
    import shutil

    from cosim.sweeps.compare import league_text

    width = shutil.get_terminal_size().columns if sys.stdout.isatty() else None
    print(league_text(table, width))
