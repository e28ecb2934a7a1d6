"""Typed, validated configuration records built from plain dictionaries.

Every configuration section is a frozen dataclass. Each field declares its bounds or choices
with :func:`setting`; :func:`from_dict` turns a nested dictionary (parsed YAML) into the
dataclass, rejecting unknown keys and out-of-range values with a :class:`ConfigError` that
names the dotted key and what was expected. Validation uses ``raise``, never ``assert``.
"""

from __future__ import annotations

import copy
import dataclasses
import datetime
import difflib
import math
import types
import typing
from typing import Any, TypeVar

from cosim.core.exceptions import ConfigError
from cosim.core.yaml_io import shown

T = TypeVar("T")


def setting(
    default: Any,
    *,
    low: float | None = None,
    high: float | None = None,
    choices: tuple[str, ...] | None = None,
    doc: str = "",
) -> Any:
    """A dataclass field with validation metadata.

    ``low``/``high`` bound numbers (inclusive); ``choices`` restricts strings.
    """
    return dataclasses.field(
        default=default, metadata={"low": low, "high": high, "choices": choices, "doc": doc}
    )


def items(item_cls: type) -> Any:
    """A list of sections, each validated as ``item_cls`` (empty by default)."""
    return dataclasses.field(default=(), metadata={"doc": item_cls.__doc__ or ""})


def section(factory: type) -> Any:
    """A nested configuration section with the nested dataclass's defaults."""
    return dataclasses.field(default_factory=factory, metadata={"doc": factory.__doc__ or ""})


def _number(value: float) -> str:
    """A bound as short as it can be written and still be itself (``1e+09``, ``0.5``; a
    bound of 0.999999999 is not shown as 1, which it refuses)."""
    short = f"{value:g}"
    return short if float(short) == value else repr(value)


def _expected(meta: dict[str, Any], kind: str) -> str:
    if meta.get("choices"):
        return "one of " + ", ".join(repr(c) for c in meta["choices"])
    low, high = meta.get("low"), meta.get("high")
    if low is not None and high is not None:
        return f"{kind} in [{_number(low)}, {_number(high)}]"
    if low is not None:
        return f"{kind} >= {_number(low)}"
    if high is not None:
        return f"{kind} <= {_number(high)}"
    return kind


def _optional(hint: Any) -> tuple[Any, bool]:
    """``(T, True)`` for a field typed ``T | None`` (unset: its owner chooses), else
    ``(hint, False)``."""
    if typing.get_origin(hint) in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(hint) if a is not type(None)]
        if len(args) == 1 and len(typing.get_args(hint)) == 2:
            return args[0], True
    return hint, False


def _convert(value: Any, hint: Any, meta: dict[str, Any], key: str) -> Any:
    """Convert one leaf value to the field's type and check its range (``None`` for a
    ``T | None`` field leaves it unset)."""
    hint, optional = _optional(hint)
    if optional and value is None:
        return None
    original = value
    if hint is bool:
        if not isinstance(value, bool):
            raise ConfigError(f"{key} = {shown(value)}: expected true or false")
        return value
    if hint is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{key} = {shown(value)}: expected {_expected(meta, 'an integer')}")
        number: float = value
    elif hint is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"{key} = {shown(value)}: expected {_expected(meta, 'a number')}")
        number = float(value)
        if not math.isfinite(number):
            raise ConfigError(f"{key} = {shown(value)}: expected a finite number")
        value = number
    elif hint is str:
        if isinstance(value, (datetime.date, datetime.datetime)):
            value = value.isoformat()  # YAML reads an unquoted date as a timestamp
        if not isinstance(value, str):
            raise ConfigError(f"{key} = {shown(value)}: expected {_expected(meta, 'a string')}")
        if meta.get("choices") and value not in meta["choices"]:
            raise ConfigError(f"{key} = {shown(value)}: expected {_expected(meta, 'a string')}")
        return value
    else:
        raise TypeError(f"unsupported config field type {hint!r} at {key}")
    low, high = meta.get("low"), meta.get("high")
    if (low is not None and number < low) or (high is not None and number > high):
        kind = "an integer" if hint is int else "a number"
        raise ConfigError(f"{key} = {shown(original)}: expected {_expected(meta, kind)}")
    return value


def _items(item_cls: type, data: Any, key: str) -> tuple[Any, ...]:
    """A list of sections (``faults: [{...}, {...}]``) as a tuple of dataclasses."""
    if data is None:
        return ()
    if not isinstance(data, list):
        raise ConfigError(f"{key} = {shown(data)}: expected a list")
    return tuple(from_dict(item_cls, item, f"{key}[{i}]") for i, item in enumerate(data))


def mapping(doc: str = "") -> Any:
    """A free-form section (a mapping, empty by default) that this module does not validate:
    its owner does (``tracker.params``, validated by a plug-in tracker's own schema)."""
    return dataclasses.field(default_factory=dict, metadata={"doc": doc})


def _mapping(data: Any, key: str) -> dict[str, Any]:
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError(f"{key} = {shown(data)}: expected a mapping of keys to values")
    return copy.deepcopy(data)


def unknown_key_error(prefix: str, name: str, known: list[str]) -> ConfigError:
    """``prefix.name`` is not a key: the closest known one suggested (difflib's ratio), else
    the known ones listed."""
    key = f"{prefix}.{name}" if prefix else name
    close = difflib.get_close_matches(name, known, n=1, cutoff=0.6)
    if close:
        keys = f"`cosim config keys {prefix}`" if prefix else "`cosim config keys`"
        suggestion = f"{prefix}.{close[0]}" if prefix else close[0]
        return ConfigError(f"unknown key {shown(key)}: did you mean {suggestion!r}? (every "
                           f"key: {keys})")
    return ConfigError(f"unknown key {shown(key)}: expected one of {', '.join(known)}")


def from_dict(cls: type[T], data: Any, prefix: str = "") -> T:
    """Build the dataclass ``cls`` from ``data``, validating every key and value.

    Keys absent from ``data`` take the dataclass defaults. ``prefix`` is the dotted path of
    this section, used in error messages.
    """
    if data is None:
        data = {}
    if not isinstance(data, dict):
        where = prefix or "the configuration"
        raise ConfigError(f"{where} = {shown(data)}: expected a mapping of keys to values")
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    unknown = sorted(set(data) - set(fields), key=str)
    if unknown:
        raise unknown_key_error(prefix, str(unknown[0]), sorted(fields))
    kwargs: dict[str, Any] = {}
    for name, value in data.items():
        key = f"{prefix}.{name}" if prefix else name
        hint = hints[name]
        if dataclasses.is_dataclass(hint):
            kwargs[name] = from_dict(hint, value, key)
        elif typing.get_origin(hint) is tuple:
            kwargs[name] = _items(typing.get_args(hint)[0], value, key)
        elif typing.get_origin(hint) is dict:
            kwargs[name] = _mapping(value, key)
        else:
            kwargs[name] = _convert(value, hint, dict(fields[name].metadata), key)
    # Defaults are validated too: a wrong default is a bug, and a section may have
    # cross-field rules in __post_init__ that raise ConfigError.
    try:
        return cls(**kwargs)
    except ConfigError as error:  # a cross-field rule of __post_init__: name the section
        if prefix:
            raise ConfigError(f"{prefix}.{error}") from None
        raise


def to_dict(config: Any) -> dict[str, Any]:
    """The configuration as plain nested dictionaries and lists (for YAML, JSON, the log)."""
    return _plain(dataclasses.asdict(config))


def _plain(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def set_dotted(data: dict[str, Any], dotted_key: str, value: Any) -> None:
    """Set ``data['a']['b']['c'] = value`` for ``dotted_key = 'a.b.c'``, creating sections.

    Whether the key exists is checked later by :func:`from_dict`, which names it.
    """
    parts = dotted_key.split(".")
    if not all(parts):
        raise ConfigError(f"--set {shown(dotted_key)}: expected a dotted key like tracker.horizon")
    node = data
    for part in parts[:-1]:
        child = node.get(part)
        if child is None:
            child = node[part] = {}
        if not isinstance(child, dict):
            raise ConfigError(f"--set {dotted_key}: '{part}' is a value, not a section")
        node = child
    node[parts[-1]] = value


def describe(cls: type, prefix: str = "") -> list[tuple[str, str, str]]:
    """Every leaf key of ``cls`` as (dotted key, default, expected) rows, for docs and help."""
    return [(info.key, repr(info.default), info.expected) for info in key_infos(cls, prefix)]


UNIT_SUFFIXES: dict[str, str] = {
    "s": "s", "ms": "ms", "ns": "ns", "m": "m", "m2": "m^2", "rad": "rad", "deg": "deg",
    "kg": "kg", "kgm2": "kg m^2", "n": "N", "nm": "N m", "w": "W", "hz": "Hz", "g": "g",
    "mps": "m/s", "mps2": "m/s^2", "radps": "rad/s", "1ps": "1/s", "1pm": "1/m",
    "npr": "N/rad", "npm": "N/m", "nspm": "N s/m", "nmprad": "N m/rad", "prad": "1/rad",
    "degpg": "deg/g", "radpmps2": "rad/(m/s^2)", "rad2ps": "rad^2/s", "rad2ps3": "rad^2/s^3",
    "m2ps": "m^2/s", "m2ps3": "m^2/s^3", "m2ps5": "m^2/s^5",
}
"""The unit each name suffix stands for (``speed_mps`` -> m/s): the naming convention of
the records and the config, read back. A name without one of these suffixes is unitless,
or names its unit in its doc (a trailing ``[unit]``)."""


def unit_of(name: str, doc: str = "") -> str:
    """The unit of a config key from its name's suffix, else a trailing ``[unit]`` of its
    doc, else ``-``."""
    stem, sep, suffix = name.rpartition("_")
    if sep and stem and suffix in UNIT_SUFFIXES:
        return UNIT_SUFFIXES[suffix]
    text = doc.rstrip()
    if text.endswith("]") and "[" in text:
        return text[text.rindex("[") + 1:-1]
    return "-"


@dataclasses.dataclass(frozen=True)
class KeyInfo:
    """One leaf key of a configuration: what ``cosim config keys`` prints."""

    key: str
    """Dotted path, ``[]`` marking a list of sections (``faults[].sensor``)."""
    kind: str
    """``bool``, ``int``, ``float`` or ``str``."""
    unit: str
    """From the name's suffix (:func:`unit_of`); ``-`` when unitless."""
    default: Any
    expected: str
    """The accepted values, as the validation's error messages state them."""
    doc: str


def key_infos(cls: type, prefix: str = "") -> list[KeyInfo]:
    """Every leaf key of ``cls`` (recursively), in declaration order."""
    rows: list[KeyInfo] = []
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        key = f"{prefix}.{f.name}" if prefix else f.name
        hint = hints[f.name]
        if dataclasses.is_dataclass(hint):
            rows.extend(key_infos(hint, key))
            continue
        if typing.get_origin(hint) is tuple:
            rows.extend(key_infos(typing.get_args(hint)[0], f"{key}[]"))
            continue
        if typing.get_origin(hint) is dict:
            rows.append(KeyInfo(f"{key}.*", "mapping", "-", {}, "keys of its owner's schema",
                                str(f.metadata.get("doc") or "")))
            continue
        hint, optional = _optional(hint)
        kind = {bool: "true/false", int: "an integer", float: "a number", str: "a string"}[hint]
        meta = dict(f.metadata)
        doc = str(meta.get("doc") or "")
        expected = _expected(meta, kind) + (" or null (unset)" if optional else "")
        rows.append(KeyInfo(key, hint.__name__, unit_of(f.name, doc), f.default,
                            expected, doc))
    return rows
