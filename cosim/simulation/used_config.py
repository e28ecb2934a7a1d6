"""The part of a resolved configuration that a run reads: what ``cosim config show`` prints.

The configuration is one record for every tracker, path and sensor (a sweep may vary a key
across them), so a resolved configuration holds some 400 keys, most of which a given run
never reads: the radar and the ACC's tuning on a lane change, the open-loop manoeuvre under
an MPC, the settings of the other trackers. :func:`used_config` keeps what the scenario and
its chosen components read:

* ``tracker:`` the keys the chosen tracker reads (:mod:`tracker.key_readers`; a plug-in
  may read any), ``acc`` only when ``tracker.acc.enabled``, ``fmu`` only for an FMU;
* ``path:`` the keys of its kind and speed profile
  (:func:`cosim.simulation.path_config.path_keys_read`);
* ``sensors:`` the enabled sensors (and ``suite``; the radar only with traffic), and
  ``estimator.noise`` without the beliefs about the others; ``ukf_*`` only for the UKF;
* ``plant:`` the Magic Formula settings only with ``plant.tyre_model = pacejka``;
* ``manoeuvre:`` only for the ``open-loop`` tracker; ``traffic:`` only when it has cars.

Everything left out is at a value the run does not read, so the pruned YAML, run as a
scenario, drives the same car the same way (the keys come back at their defaults).
"""

from __future__ import annotations

from typing import Any

from cosim.simulation.path_config import path_keys_read
from cosim.simulation.unread_keys import PACEJKA_ONLY_PLANT_KEYS
from tracker.key_readers import is_read_by

TOP_LEVEL_ONLY_WHEN = {"manoeuvre": "open-loop"}
"""Sections read only by one tracker."""


def _tracker_section(tracker: dict[str, Any], name: str, prefix: str = "") -> dict[str, Any]:
    kept: dict[str, Any] = {}
    for key, value in tracker.items():
        dotted = f"{prefix}{key}"
        if dotted == "acc" and not (isinstance(value, dict) and value.get("enabled")):
            continue
        if dotted == "fmu" and not name.startswith("fmu:"):
            continue
        if isinstance(value, dict) and value:
            inner = _tracker_section(value, name, f"{dotted}.")
            if inner:
                kept[key] = inner
        elif is_read_by(name, dotted):
            kept[key] = value
    return kept


def used_config(config: dict[str, Any]) -> dict[str, Any]:
    """``config`` (a resolved configuration as plain dictionaries, :func:`to_dict`) with the
    keys its run does not read left out (module docstring)."""
    used = dict(config)
    tracker = config.get("tracker", {})
    name = str(tracker.get("name", ""))
    used["tracker"] = _tracker_section(tracker, name)
    for section, reader in TOP_LEVEL_ONLY_WHEN.items():
        if name != reader:
            used.pop(section, None)
    path = config.get("path", {})
    if path.get("kind") and path.get("speed_profile"):
        read = path_keys_read(str(path["kind"]), str(path["speed_profile"]))
        used["path"] = {k: v for k, v in path.items() if k in read}
    sensors = config.get("sensors", {})
    traffic = bool(config.get("traffic"))
    unused = {k for k, v in sensors.items() if isinstance(v, dict)
              and (not v.get("enabled", True) or (k == "radar" and not traffic))}
    used["sensors"] = {k: v for k, v in sensors.items() if k not in unused}
    estimator = dict(config.get("estimator", {}))
    if isinstance(estimator.get("noise"), dict):  # the beliefs about sensors it never sees
        estimator["noise"] = {k: v for k, v in estimator["noise"].items()
                              if not any(k.startswith(f"{s}_") for s in unused)}
    if estimator.get("name") != "ukf":
        estimator = {k: v for k, v in estimator.items() if not k.startswith("ukf_")}
    used["estimator"] = estimator
    plant = config.get("plant", {})
    if plant.get("tyre_model", "pacejka") != "pacejka":
        used["plant"] = {k: v for k, v in plant.items() if k not in PACEJKA_ONLY_PLANT_KEYS}
    if not config.get("traffic"):
        used.pop("traffic", None)
    return used
