"""``cosim cache``: the compiled libraries' folder, what it holds, and emptying it (the
libraries, and the results kept there by :mod:`cosim.core.built_on_disk`)."""

from __future__ import annotations

import argparse
import collections
from typing import Any

from cosim.cli.common import Handler


def add_parsers(commands: Any) -> dict[str, Handler]:
    cache = commands.add_parser(
        "cache", help="show the compiled-code cache (its folder, size and bound) or clear it")
    cache.add_argument("--clear", action="store_true",
                       help="remove every compiled library and kept model (the next run "
                            "builds what it needs)")
    return {"cache": command}


def command(args: argparse.Namespace) -> int:
    from cosim.core.compiled_cache import cache_dir, clear, entries, limit_bytes

    folder, limit = cache_dir(), limit_bytes()
    if args.clear:
        removed = clear()
        print(f"removed {len(removed)} entries ({_mb(removed)}) from {folder}")
        return 0
    found = entries()
    print(f"{folder}: {len(found)} entries (compiled libraries, kept models), {_mb(found)} "
          f"of at most {limit / 1e6:.0f} MB (COSIM_CACHE_MAX_MB; the least recently used go "
          "first)")
    by_name: dict[str, list[Any]] = collections.defaultdict(list)
    for entry in found:
        by_name[entry.name].append(entry)
    for name, group in sorted(by_name.items(), key=lambda item: -sum(e.size_bytes
                                                                      for e in item[1])):
        print(f"  {name:<28} {len(group):>4} x  {_mb(group):>9}")
    if found:
        print("cosim cache --clear removes them all")
    return 0


def _mb(found: Any) -> str:
    return f"{sum(e.size_bytes for e in found) / 1e6:.1f} MB"
