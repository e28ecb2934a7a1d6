"""``cosim identify``: the plant's handling figures and fitted bicycle models."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from cosim.cli.common import Handler, format_value, json_ready

IDENTIFY_SCENARIO = "lane-change"
"""`cosim identify` identifies the plant of this scenario's config (with the overrides)."""


def add_parsers(commands: Any) -> dict[str, Handler]:
    identify = commands.add_parser(
        "identify", help="identify the plant's bicycle-model parameters and actuator lags")
    identify.add_argument("--config", metavar="FILE.yaml", action="append",
                          help="YAML merged over the lane-change scenario; repeat to merge "
                               "several in order")
    identify.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                          dest="overrides", help="override a config key, e.g. plant.mass_kg=2000")
    identify.add_argument("--json", action="store_true", help="print one JSON object")
    return {"identify": command}


def command(args: argparse.Namespace) -> int:
    from cosim.identification import identify
    from cosim.simulation.scenario_config import load_config

    config = load_config(IDENTIFY_SCENARIO, args.config, args.overrides)
    model = identify(config.plant, config.tracker.model, config.sim.physics_dt_s)
    if args.json:
        print(json.dumps(json_ready(model.to_dict())))
        return 0
    rows = [(quantity, format_value(value), unit, residual)
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
