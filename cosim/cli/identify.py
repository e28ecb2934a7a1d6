"""``cosim identify``: the plant's handling figures and fitted bicycle models."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from cosim.cli.common import Handler, format_value, json_ready

if TYPE_CHECKING:
    from cosim.plant.data_sheet import DataSheetBelief

DATA_SHEET_LINE = "# From the car's data sheet:"
"""How a belief file's line naming what came from the car's data sheet begins."""

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
    identify.add_argument("--belief-out", metavar="FILE.yaml",
                          help="also write the car's belief to this YAML file: the identified "
                               "tracker.model.* keys, the car's other figures, and the "
                               "filter's tyre, steering and roll beliefs (estimator.*) from "
                               "its data sheet; `cosim run ... --config car.yaml --config "
                               "FILE.yaml` drives the car with a controller and a filter "
                               "that know it")
    identify.add_argument("--force", action="store_true",
                          help="replace an existing --belief-out file")
    return {"identify": command}


def command(args: argparse.Namespace) -> int:
    from cosim.identification import identify
    from cosim.simulation.scenario_config import load_config

    config = load_config(IDENTIFY_SCENARIO, args.config, args.overrides)
    sheet = None
    if args.belief_out is not None:  # refused before the identification, not after it
        from cosim.identification.model import BELIEF_FIELDS
        from cosim.log.safe_file import check_output_path
        from cosim.plant.data_sheet import data_sheet_belief

        check_output_path(Path(args.belief_out), "--belief-out", args.force,
                          args.config or ())
        sheet = data_sheet_belief(config.plant, config.tracker.model, BELIEF_FIELDS)
    model = identify(config.plant, config.tracker.model, config.sim.physics_dt_s)
    if sheet is not None:
        _write_belief(Path(args.belief_out), model.belief(), sheet, args)
        print(f"cosim: the identified belief is in {args.belief_out}: run with "
              f"--config {args.belief_out} after the car's own config", file=sys.stderr)
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


def _write_belief(path: Path, fitted: dict[str, float], sheet: DataSheetBelief,
                  args: argparse.Namespace) -> None:
    """``tracker: {model: ...}`` (the fitted keys, then the data sheet's) and ``estimator:``
    as YAML, with a header saying where each came from; written beside and renamed into
    place (a crash leaves no half file)."""
    import datetime

    import yaml

    from cosim.log.safe_file import PendingFile
    from cosim.plant.data_sheet import ESTIMATOR_SOURCES

    source = " ".join([*(f"--config {c}" for c in args.config or ()),
                       *(f"--set {o}" for o in args.overrides)]) or "the default sedan"
    figures = ", ".join(sheet.model) or "no figure other than the controller's"
    header = (f"# The controller's belief about the plant of {source},\n"
              f"# identified by cosim identify on {datetime.date.today().isoformat()}.\n"
              "# Merge it after the car's own config: cosim run SCENARIO --config car.yaml "
              f"--config {path.name}\n"
              f"{DATA_SHEET_LINE} {figures}; {ESTIMATOR_SOURCES}.\n")
    model: dict[str, float | str] = {name: float(f"{value:.6g}")
                                     for name, value in fitted.items()}
    text = header + yaml.safe_dump({"tracker": {"model": {**model, **sheet.model}},
                                    "estimator": sheet.estimator}, sort_keys=False)
    pending = PendingFile(path)
    try:
        pending.file.write(text.encode("utf-8"))
        pending.file.flush()
        pending.publish()
    finally:
        pending.close()
