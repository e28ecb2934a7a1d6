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
    cosim cache [--clear]
    cosim --version

The options and exit codes are a stable interface: scripts and outside tests rely on them.

Exit codes of ``cosim run``: 0 when the run's outcome is ``ok`` (and no --fail-if holds);
2 on bad input (one line on stderr naming the bad value and what was expected); 3 when the
run ended badly (its ``outcome`` is ``spun``, ``rolled_over``, ``off_road``,
``end_of_path``, ``diverged`` ...: see cosim.simulation.outcome) or a --fail-if condition
holds (the log is complete up to the end or the abort in both cases); 130 on an interrupt;
1 when a file cannot be written (a full disk) or a standard stream is closed. A run's
simulation goes on in a child process that ``cosim run`` watches (cosim.cli.guard): when
foreign code ends that process (an FMU's library that crashes, a plug-in calling
``os._exit``), the command says so in one line, names the likely component and the log up to
then, and exits 3.
A sweep exits 3 when a run failed (an error, a bad outcome, a failed pass criterion; 0 with
--exit-zero) and every run has a row (a run whose worker process died included: the results
say so), 130 on an interrupt (finish with --resume).

One module per command (or family of commands), each adding its parsers and returning its
handlers: :mod:`~cosim.cli.run`, :mod:`~cosim.cli.inspect_log`, :mod:`~cosim.cli.views`
(plot, render), :mod:`~cosim.cli.export`, :mod:`~cosim.cli.components` (scenarios,
trackers, estimators), :mod:`~cosim.cli.compare`, :mod:`~cosim.cli.identify`,
:mod:`~cosim.cli.sweep`, :mod:`~cosim.cli.config_command`. Each imports the machinery it
needs when it runs, so that ``cosim --help`` stays quick.
"""

from __future__ import annotations

import argparse
import sys
import warnings
from collections.abc import Sequence
from typing import Any

from cosim.cli import (
    cache,
    compare,
    components,
    config_command,
    envelope,
    export,
    identify,
    inspect_log,
    run,
    sweep,
    views,
)
from cosim.cli.common import (
    EXIT_BAD_OUTCOME,
    EXIT_INTERRUPT,
    EXIT_IO,
    EXIT_USAGE,
    Handler,
    Parser,
    one_line_warning,
    say,
    silence_stdout,
    single_threaded_blas,
)
from cosim.core.exceptions import CosimError
from cosim.core.interrupts import drop_unraisable_interrupts

__all__ = ["EXIT_BAD_OUTCOME", "EXIT_INTERRUPT", "EXIT_IO", "EXIT_USAGE", "main"]

COMMAND_MODULES = (run, inspect_log, views, export, components, compare, identify, sweep,
                   envelope, config_command, cache)
"""Every command's module, in the order ``cosim --help`` lists their commands."""


def build_parser() -> tuple[argparse.ArgumentParser, dict[str, Handler]]:
    """The ``cosim`` parser and the handler of each of its commands."""
    from cosim import __version__

    parser = Parser(
        prog="cosim", formatter_class=argparse.RawDescriptionHelpFormatter,
        description=__doc__.split("\n\n")[1],
        epilog="Every command has its own --help. Configuration keys and their units: "
        "`cosim config keys`; what a run would use: `cosim config show SCENARIO`.")
    parser.add_argument("--version", action="version", version=f"cosim {__version__}")
    commands = parser.add_subparsers(dest="command", parser_class=Parser,
                                     metavar="COMMAND")
    handlers: dict[str, Handler] = {}
    for module in COMMAND_MODULES:
        handlers.update(module.add_parsers(commands))
    return parser, handlers


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``cosim`` console script.

    ``argv`` None reads this process's command line, and ``cosim run`` then runs the
    simulation in a child process it watches (:mod:`cosim.cli.guard`: foreign native code
    that ends its process leaves a line saying so and the log); a list runs every command in
    this process (tests, embedding)."""
    if argv is None:  # before anything imports numpy
        single_threaded_blas()
    parser, handlers = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:  # `cosim` alone: what it can do, not just "required"
        parser.print_help()
        say("cosim: error: expected a command (first time? `cosim run lane-change`)")
        return EXIT_USAGE
    args.reporter = None
    if argv is None:  # this process is the command's own
        drop_unraisable_interrupts()
    if argv is None and args.command == "run":
        from cosim.cli.guard import Death, guarded

        def body(reporter: Any) -> int:
            args.reporter = reporter
            return _dispatch(args, handlers)

        ended = guarded(body)
        return run.died(args, ended) if isinstance(ended, Death) else ended
    return _dispatch(args, handlers)


def _dispatch(args: argparse.Namespace, handlers: dict[str, Handler]) -> int:
    """Run the command of ``args``: its exit code, every user error as one line."""
    try:
        with warnings.catch_warnings():
            warnings.showwarning = one_line_warning
            code = handlers[args.command](args)
        sys.stdout.flush()  # a full or closed stdout fails here, not at exit
        return code
    except CosimError as error:
        say(f"cosim: error: {error}")
        return EXIT_USAGE
    except KeyboardInterrupt:  # before or after a run's loop (the loop handles its own)
        say("cosim: interrupted")
        return EXIT_INTERRUPT
    except BrokenPipeError:  # `cosim ... | head`: the reader has what it wanted
        silence_stdout()
        return 0
    except OSError as error:  # a full disk, a full stdout
        silence_stdout()
        where = f"{error.filename!r}" if error.filename else "a file or standard output"
        say(f"cosim: error: cannot write {where}: {error.strerror or error}")
        return EXIT_IO
