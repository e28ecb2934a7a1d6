"""``cosim scenarios``, ``cosim trackers``, ``cosim estimators``: what there is to run."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from typing import Any

from cosim.cli.common import Handler


def add_parsers(commands: Any) -> dict[str, Handler]:
    commands.add_parser("scenarios", help="list the built-in scenarios")
    commands.add_parser("trackers", help="list the trackers: built in and installed plug-ins")
    commands.add_parser("estimators",
                        help="list the estimators: built in and installed plug-ins")
    return {"scenarios": scenarios, "trackers": trackers, "estimators": estimators}


def scenarios(args: argparse.Namespace) -> int:
    from cosim.simulation.scenario_config import builtin_scenarios

    del args
    for name, description in builtin_scenarios().items():
        print(f"{name:<20} {description}")
    return 0


def trackers(args: argparse.Namespace) -> int:
    from cosim.core.plugins import entry_point_names
    from tracker.config import PLUGIN_GROUP
    from tracker.registry import TRACKER_NAMES

    del args
    return _print_components(TRACKER_NAMES, entry_point_names(PLUGIN_GROUP), PLUGIN_GROUP,
                             "--tracker")


def estimators(args: argparse.Namespace) -> int:
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
