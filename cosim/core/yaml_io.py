"""Reading YAML the way a user means it, and showing bad values in bounded space.

PyYAML implements YAML 1.1, which reads ``1e-5`` and ``2e3`` (no dot) as strings; YAML
1.2 (the YAML 1.2.2 specification, 2021, core schema) reads them as floats. :class:`Loader`
uses the 1.2 float pattern, so exponents mean numbers in every scenario, config, sweep spec
and ``--set`` value. It also refuses a key given twice in one mapping (YAML 1.2 requires
keys to be unique; PyYAML silently keeps the last one) naming the key and its line.

:func:`read_yaml_file` reads a file as UTF-8 text (a UTF-8 byte-order mark is allowed)
and turns every failure (unreadable, not UTF-8, not YAML, duplicate key) into one
:class:`ConfigError` line. :func:`shown` is the ``repr`` every error message uses for a
user's value: at most :data:`SHOWN_CHARS` characters, computed in bounded time even for a
value blown up by YAML anchors (``&a [*b, *b, ...]``).
"""

from __future__ import annotations

import re
import reprlib
from pathlib import Path
from typing import Any

import yaml

from cosim.core.exceptions import ConfigError

SHOWN_CHARS = 200
"""At most this many characters of a user's value are echoed in an error message."""

_FLOAT_1_2 = re.compile(r"""^(?:[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?
    |[-+]?\.(?:inf|Inf|INF)
    |\.(?:nan|NaN|NAN))$""", re.X)


class Loader(yaml.SafeLoader):
    """PyYAML's safe loader with YAML 1.2 floats and unique keys."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        seen: set[Any] = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=True)
            try:
                duplicate = key in seen
            except TypeError:  # an unhashable key: PyYAML reports it below
                continue
            if duplicate:
                raise ConfigError(f"line {key_node.start_mark.line + 1}: key {shown(key)} "
                                  "given twice: expected each key once")
            seen.add(key)
        return super().construct_mapping(node, deep)


# Integers keep YAML 1.1's resolver (tried first); everything else that is a 1.2 float is
# a float. Copy the table so the stock SafeLoader is left as it is.
Loader.yaml_implicit_resolvers = {
    first: [(tag, regexp) for tag, regexp in resolvers if tag != "tag:yaml.org,2002:float"]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
Loader.add_implicit_resolver("tag:yaml.org,2002:float", _FLOAT_1_2,
                             list("-+0123456789."))


def _short_repr() -> reprlib.Repr:
    short = reprlib.Repr()
    short.maxstring = SHOWN_CHARS
    short.maxother = SHOWN_CHARS
    short.maxlevel = 3
    short.maxlist = short.maxtuple = short.maxdict = short.maxset = 8
    return short


def shown(value: Any) -> str:
    """``repr(value)``, at most :data:`SHOWN_CHARS` characters (bounded work)."""
    text = _short_repr().repr(value)
    return text if len(text) <= SHOWN_CHARS else text[: SHOWN_CHARS - 3] + "..."


MAX_DEPTH = 64
"""Deepest nesting of lists and mappings a configuration may have (a real one has about
six levels; a value nested thousands deep would exhaust Python's recursion on the way)."""


def dumps(data: Any) -> str:
    """``data`` (plain dictionaries, lists, strings, numbers) as block-style YAML, the keys
    in their order: PyYAML's own representer, written by libyaml's emitter where PyYAML was
    built with it (the same text as PyYAML's pure-Python emitter, a quarter of its time: a
    run's configuration in 2 ms instead of 7, 30 for a process's first), else by the
    pure-Python one."""
    dumper = getattr(yaml, "CSafeDumper", yaml.SafeDumper)
    return yaml.dump(data, Dumper=dumper, sort_keys=False)


def loads(text: str) -> Any:
    """Parse YAML text with :class:`Loader` (errors as PyYAML's or :class:`ConfigError`);
    a document nested deeper than :data:`MAX_DEPTH` is a ConfigError."""
    try:
        value = yaml.load(text, Loader=Loader)  # noqa: S506 - Loader is a SafeLoader
    except RecursionError:
        raise ConfigError(f"nested deeper than {MAX_DEPTH} levels of lists or mappings: "
                          "expected a configuration value") from None
    if _depth(value) > MAX_DEPTH:
        raise ConfigError(f"nested deeper than {MAX_DEPTH} levels of lists or mappings: "
                          "expected a configuration value")
    return value


def _depth(value: Any) -> int:
    """How deep lists and mappings nest in ``value`` (without recursion; a list or mapping
    that YAML aliases share is walked once, so an alias bomb costs its distinct nodes)."""
    deepest, stack, seen = 0, [(value, 0)], set()
    while stack:
        item, level = stack.pop()
        if isinstance(item, (list, dict)):
            if id(item) in seen:
                continue
            seen.add(id(item))
            level += 1
            deepest = max(deepest, level)
            if deepest > MAX_DEPTH:
                return deepest
            stack.extend((child, level) for child in
                         (item.values() if isinstance(item, dict) else item))
    return deepest


def read_yaml_file(path: Path, what: str) -> Any:
    """The YAML document in ``path``; every failure is one ConfigError naming ``what``."""
    where = f"{what} {str(path)!r}"
    try:
        raw = path.read_bytes()
    except OSError as error:
        raise ConfigError(f"{where}: cannot read ({error.strerror})") from None
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as error:
        raise ConfigError(f"{where}: byte {error.start} is not UTF-8: expected a UTF-8 "
                          "text file (YAML)") from None
    if "\x00" in text:
        raise ConfigError(f"{where}: holds NUL characters: expected a UTF-8 text file "
                          "(YAML; UTF-16 is not accepted)")
    try:
        return loads(text)
    except ConfigError as error:
        raise ConfigError(f"{where}: {error}") from None
    except yaml.YAMLError as error:
        mark = getattr(error, "problem_mark", None)
        line = f" line {mark.line + 1}" if mark is not None else ""
        problem = getattr(error, "problem", None) or "syntax error"
        raise ConfigError(f"{where}:{line} is not valid YAML ({problem})") from None
    except RecursionError:
        raise ConfigError(f"{where}: nested too deeply: expected a YAML mapping") from None
