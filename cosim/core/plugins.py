"""Finding code from outside cosim: an import path ``package.module:Class`` or an entry point.

A tracker or an estimator may come from the user's own package. ``tracker.name`` (and
``estimator.name``) then holds either

- an import path ``my_pkg.my_module:MyTracker``: the module is imported, the attribute read;
- the name of an entry point in the group ``cosim.trackers`` (``cosim.estimators``) that an
  installed distribution declares in its ``pyproject.toml``::

      [project.entry-points."cosim.trackers"]
      my-pursuit = "my_pkg.my_module:MyTracker"

Every failure is a :class:`cosim.core.exceptions.PluginError` of one line naming the path and
what was expected (the command line exits with code 2). Entry points are read with
:func:`importlib.metadata.entry_points` (the standard library's reader of the packaging
specification "Entry points", packaging.python.org).
"""

from __future__ import annotations

import importlib
import re

from cosim.core.exceptions import PluginError
from cosim.core.moved_modules import moved_to

IMPORT_PATH = re.compile(r"^[A-Za-z_][\w.]*:[A-Za-z_][\w.]*$")
"""``module.path:Attribute.path``, the form of an entry point's object reference."""


def is_import_path(name: str) -> bool:
    """Whether ``name`` has the form ``package.module:Class``."""
    return bool(IMPORT_PATH.match(name))


def missing_members(obj: object, protocol: type) -> list[str]:
    """The members of ``protocol`` (its methods, then its annotated attributes) that
    ``obj`` lacks: what a plug-in class must add to implement it."""
    members = [*(name for name, value in vars(protocol).items()
                 if callable(value) and not name.startswith("_")),
               *vars(protocol).get("__annotations__", {})]
    return [name for name in members if not hasattr(obj, name)]


def entry_point_names(group: str) -> dict[str, str]:
    """Installed entry points of ``group``: name -> ``module:attribute`` (sorted by name).

    :mod:`importlib.metadata` is imported here, when a name is looked up: it imports the
    standard library's e-mail parser and zip reader, some 8 ms of every process start that
    names only built-in components."""
    import importlib.metadata

    found = {ep.name: ep.value for ep in importlib.metadata.entry_points(group=group)}
    return dict(sorted(found.items()))


def load_object(name: str, group: str, key: str) -> object:
    """The object ``name`` refers to: an import path, or an entry point of ``group``.

    ``key`` is the configuration key being resolved (``tracker.name``), for the messages.
    """
    target = name if is_import_path(name) else entry_point_names(group).get(name)
    if target is None:
        raise PluginError(f"{key} = {name!r}: no entry point {name!r} in group {group!r}: "
                          "expected a built-in name, an installed plug-in or module:Class")
    module_name, _, attribute = target.partition(":")
    where = f"{key} = {name!r}" + ("" if target == name else f" (entry point {target!r})")
    try:
        obj: object = importlib.import_module(module_name)
    except ModuleNotFoundError as error:
        if error.name is not None and module_name.split(".")[0] == error.name.split(".")[0]:
            # The module itself is not on the import path (a file in the current folder
            # is not: the `cosim` command's path starts at its own folder).
            raise PluginError(
                f"{where}: no module {error.name!r} on Python's import path (the installed "
                "packages and PYTHONPATH): expected an installed package, or the folder "
                f"holding {error.name.split('.')[0]}.py on PYTHONPATH (for the current "
                "folder: PYTHONPATH=. cosim ...)") from None
        moved = moved_to(error.name or "")
        if moved is not None:
            raise PluginError(f"{where}: importing {module_name!r} needs the module "
                              f"{error.name!r}, which cosim moved to {moved!r}: expected "
                              f"'import {moved}' there instead") from None
        raise PluginError(f"{where}: importing {module_name!r} needs the module "
                          f"{error.name!r}, which is not installed: expected it installed "
                          "in the environment cosim runs in") from None
    except KeyboardInterrupt:
        raise
    except BaseException as error:  # noqa: BLE001 - the user's module failed while importing
        raise PluginError(f"{where}: importing {module_name!r} raised "
                          f"{type(error).__name__}: {error}") from None
    for part in attribute.split("."):
        if not hasattr(obj, part):
            raise PluginError(f"{where}: module {module_name!r} has no attribute "
                              f"{attribute!r}: expected a class defined there")
        obj = getattr(obj, part)
    return obj
