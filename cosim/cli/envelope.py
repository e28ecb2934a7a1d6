"""``cosim envelope``: how far a mismatch may go before a requirement fails, searched for
by root-finding on its robustness over a seed ensemble (:mod:`cosim.sweeps.envelope`)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from cosim.cli.common import EXIT_INTERRUPT, Handler, add_pool_options, refuse_live
from cosim.core.exceptions import CosimError


def add_parsers(commands: Any) -> dict[str, Handler]:
    envelope = commands.add_parser(
        "envelope", help="find the mismatch at which a requirement starts to fail")
    envelope.add_argument("spec", metavar="SPEC.yaml",
                          help="the envelope spec (see cosim.sweeps.envelope_spec)")
    add_pool_options(envelope)
    envelope.add_argument("--out", metavar="DIR",
                          help="output directory (default logs/envelope-<spec>)")
    envelope.add_argument("--resume", action="store_true",
                          help="go on with the search in --out DIR (same spec)")
    envelope.add_argument("--force", action="store_true",
                          help="start afresh in a --out DIR that has files")
    return {"envelope": command}


def command(args: argparse.Namespace) -> int:
    refuse_live(args, "envelope")
    from cosim.sweeps.envelope import run_envelope

    if not Path(args.spec).is_file():
        raise CosimError(f"{args.spec!r}: no such file (expected an envelope spec YAML)")
    if args.resume and args.out is None:
        raise CosimError("--resume: expected --out DIR, the folder of the search to go on with")
    out = Path(args.out) if args.out is not None else \
        Path("logs") / f"envelope-{Path(args.spec).stem}"
    try:
        result = run_envelope(args.spec, out, args.workers, args.backend, args.resume,
                              args.force)
    except KeyboardInterrupt:
        print(f"cosim: envelope search interrupted; finished runs are kept: go on with "
              f"`cosim envelope {args.spec} --out {out} --resume`", file=sys.stderr)
        return EXIT_INTERRUPT
    answers = (out / "summary.md").read_text().split("## The answer\n\n")[1].split("\n\n")[0]
    print(answers)
    print(f"envelope: {result.runs} runs ({result.ran} now) in {result.wall_time_s:.1f} s")
    for path in result.files:
        print(f"  {path}")
    return 0
