"""``cosim config``: what a run would use, and which keys exist.

    cosim config show SCENARIO [--config FILE.yaml] [--tracker NAME] [--estimator NAME]
                               [--seed N] [--duration S] [--set key.path=value ...]
    cosim config keys [PREFIX]

``show`` resolves the configuration exactly as ``cosim run`` would (same sources, same
order, same validation) and prints as YAML what the run reads
(:func:`cosim.simulation.used_config.used_config`), or with ``--all`` every key; either YAML
is itself a scenario file, which runs the same car the same way. ``keys`` lists every key
with its type, unit (from the name's suffix: ``_s`` seconds, ``_mps`` m/s ...), default,
accepted values and a line of documentation, read from the config dataclasses themselves
(:func:`cosim.core.config_fields.key_infos`), so the list cannot drift from what the
validation accepts.
"""

from __future__ import annotations

import argparse
import difflib
from typing import Any

from cosim.cli.common import Handler, Parser
from cosim.core.exceptions import ConfigError


def add_parsers(commands: Any) -> dict[str, Handler]:
    """Add ``config show`` and ``config keys`` to the ``cosim`` sub-commands."""
    config = commands.add_parser(
        "config", help="print the resolved configuration of a run, or the list of keys",
        description="Print the resolved configuration of a run (show), or every "
        "configuration key with its unit, default and accepted values (keys).")
    actions = config.add_subparsers(dest="config_command", required=True,
                                    parser_class=Parser)
    show = actions.add_parser(
        "show", help="the configuration a run would use, as YAML (a valid scenario file)")
    show.add_argument("scenario", help="built-in scenario name (see `cosim scenarios`) or YAML")
    show.add_argument("--config", metavar="FILE.yaml", action="append",
                      help="YAML merged over the scenario; repeat to merge several in order "
                           "(a later file wins a key both set)")
    show.add_argument("--tracker", metavar="NAME", help="tracker.name")
    show.add_argument("--estimator", metavar="NAME", help="estimator.name")
    show.add_argument("--seed", type=int, metavar="N", help="the run's seed")
    show.add_argument("--duration", type=float, metavar="S", help="sim.duration_s")
    show.add_argument("--all", action="store_true",
                      help="every key, also those the run does not read")
    show.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                      dest="overrides", help="override a config key, e.g. tracker.horizon=30")
    keys = actions.add_parser(
        "keys", help="every configuration key: unit, default, accepted values, meaning")
    keys.add_argument("prefix", nargs="?", default="",
                      help="only keys starting with this, e.g. tracker or plant.tyre")
    return {"config": command}


def resolved_yaml(config: Any) -> str:
    """The configuration as the YAML a run logs (metadata ``run``, ``config_yaml``)."""
    from cosim.core import yaml_io
    from cosim.core.config_fields import to_dict

    return yaml_io.dumps(to_dict(config))


def _format_default(value: Any) -> str:
    if value is None:
        return "unset"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return value if value else '""'
    return repr(value)


def keys_table(prefix: str = "") -> list[tuple[str, str, str, str, str]]:
    """``(key, unit, default, accepted values, doc)`` rows of every key starting with
    ``prefix``; an unknown prefix is a :class:`ConfigError` naming the sections."""
    from cosim.core.config_fields import key_infos
    from cosim.core.key_aliases import canonical_key
    from cosim.plant.traffic import TrafficCarConfig
    from cosim.simulation.scenario_config import ScenarioConfig

    prefix = canonical_key(prefix, "config keys") if prefix else prefix
    infos = key_infos(ScenarioConfig)
    # Each traffic car's keys, under a placeholder, or under the car the prefix names.
    parts = prefix.split(".")
    named = parts[0] == "traffic" and len(parts) > 1 and not "NAME".startswith(parts[1])
    infos += key_infos(TrafficCarConfig, f"traffic.{parts[1] if named else 'NAME'}")
    rows = [(i.key, i.unit, _format_default(i.default), i.expected, i.doc)
            for i in infos if i.key.startswith(prefix)]
    if not rows:
        # The closest name at the prefix's depth under the same parent ("tire": "tyre").
        siblings = sorted({i.key.split(".")[len(parts) - 1] for i in infos
                           if i.key.split(".")[:len(parts) - 1] == parts[:-1]
                           and len(i.key.split(".")) >= len(parts)})
        close = difflib.get_close_matches(parts[-1].replace("tire", "tyre"), siblings, n=1,
                                          cutoff=0.6)
        if close:
            shown = ".".join([*parts[:-1], close[0]])
            raise ConfigError(f"config keys {prefix!r}: no key starts with it; did you mean "
                              f"{shown!r}?")
        sections = sorted({i.key.split(".")[0].removesuffix("[]") for i in infos})
        raise ConfigError(f"config keys {prefix!r}: no key starts with it; expected a prefix "
                          f"such as one of {', '.join(sections)}")
    return rows


def _print_sources(config_file: list[str] | None) -> None:
    """A comment line per ``--config`` file naming the keys it set (a key two files set is
    under the later one, whose value is used)."""
    if not config_file:
        return
    from cosim.simulation.scenario_config import config_sources

    by_file: dict[str, list[str]] = {path: [] for path in config_file}
    for key, path in config_sources(config_file).items():
        by_file[path].append(key)
    for path, keys in by_file.items():
        print(f"# set by --config {path}: {', '.join(keys) if keys else 'nothing it alone sets'}")


def command(args: argparse.Namespace) -> int:
    """``cosim config show|keys``."""
    if args.config_command == "show":
        from cosim.simulation.scenario_config import load_config

        config = load_config(args.scenario, args.config, args.overrides, args.seed,
                             args.duration, args.tracker, args.estimator)
        _print_sources(args.config)
        if args.all:
            print(resolved_yaml(config), end="")
            return 0
        from cosim.core import yaml_io
        from cosim.core.config_fields import to_dict
        from cosim.simulation.used_config import used_config

        print("# What this run reads; the keys it does not read are left out "
              "(`cosim config show --all` prints them).")
        print(yaml_io.dumps(used_config(to_dict(config))), end="")
        return 0
    rows = keys_table(args.prefix)
    header = ("key", "unit", "default", "accepted", "meaning")
    widths = [max(len(row[i]) for row in [header, *rows]) for i in range(4)]
    for row in [header, *rows]:
        cells = [f"{cell:<{width}}" for cell, width in zip(row[:4], widths, strict=True)]
        print(("  ".join([*cells, row[4]])).rstrip())
    return 0
