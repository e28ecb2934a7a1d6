"""``cosim sweep``: one scenario over a grid or a random sample of parameters and seeds.

Exit codes, for a CI job to gate on: 0 when every run of the sweep passes its criteria; 3
when a run fails them (a run whose outcome is not ``ok`` fails every criterion, an error
too); ``--exit-zero`` gives 0 for a sweep that ran to its end whatever its runs did (for
those who only want the tables). 2 for bad input, 1 when its files cannot be written, 130
on an interrupt (the finished rows are kept for ``--resume``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from cosim.cli.common import (
    EXIT_BAD_OUTCOME,
    EXIT_INTERRUPT,
    EXIT_IO,
    Handler,
    add_pool_options,
    refuse_live,
)
from cosim.core.exceptions import CosimError


def add_parsers(commands: Any) -> dict[str, Handler]:
    sweep = commands.add_parser(
        "sweep", help="run a scenario over a grid or random sample of parameters and seeds")
    sweep.add_argument("spec", metavar="SPEC.yaml", help="the sweep spec (see cosim.sweeps.spec)")
    add_pool_options(sweep)
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
    sweep.add_argument("--exit-zero", action="store_true",
                       help="exit 0 when the sweep finishes even if runs fail their criteria "
                            "(default: exit 3 when any run fails)")
    return {"sweep": command}


def command(args: argparse.Namespace) -> int:
    refuse_live(args, "sweep")
    from cosim.sweeps.driver import check_sweep_dir, default_out_dir, run_sweep

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
    failed = outcome.finished - outcome.passed
    if failed and not args.exit_zero:
        print(f"cosim: {failed} of {outcome.finished} runs fail the sweep's criteria "
              f"(see {out / 'summary.md'}); exit code 3 (--exit-zero: 0)", file=sys.stderr)
        return EXIT_BAD_OUTCOME
    return 0
