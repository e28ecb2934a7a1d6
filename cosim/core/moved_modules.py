"""Where the project's modules went when they were regrouped into layers (docs/architecture.md):
old dotted name -> today's. A user's plug-in or script written against an old path gets the
new one named (:func:`cosim.core.plugins.load_object`, ``docs/api.md``) instead of a bare
``No module named``. Taken from the repository's history of renames (``git log
--diff-filter=R``), each followed to the module that exists today."""

from __future__ import annotations

from types import MappingProxyType

MOVED_MODULES = MappingProxyType({
    "cosim.compiled_function": "cosim.core.compiled_function",
    "cosim.config_cli": "cosim.cli.config_command",
    "cosim.config_fields": "cosim.core.config_fields",
    "cosim.disturbances": "cosim.plant.disturbances",
    "cosim.exceptions": "cosim.core.exceptions",
    "cosim.faults": "cosim.sensing.faults",
    "cosim.foxglove": "cosim.log.foxglove",
    "cosim.initial_state": "cosim.core.initial_state",
    "cosim.inspect_export": "cosim.log.export",
    "cosim.log_names": "cosim.log.names",
    "cosim.log_reader": "cosim.log.reader",
    "cosim.low_level": "cosim.plant.low_level",
    "cosim.maneuver_metrics": "cosim.simulation.manoeuvre_metrics",
    "cosim.mcap_schemas": "cosim.log.schemas",
    "cosim.metrics": "cosim.simulation.metrics",
    "cosim.plant": "cosim.plant.car",
    "cosim.plant.compiled_function": "cosim.core.compiled_function",
    "cosim.plant.tire_model": "cosim.plant.tyre_model",
    "cosim.plots.ensemble": "cosim.sweeps.ensemble",
    "cosim.plugins": "cosim.core.plugins",
    "cosim.recorder": "cosim.log.recorder",
    "cosim.records": "cosim.core.records",
    "cosim.render": "cosim.plots.render",
    "cosim.runner": "cosim.simulation.runner",
    "cosim.scenario_config": "cosim.simulation.scenario_config",
    "cosim.sedan_model": "cosim.plant.sedan_model",
    "cosim.sensors": "cosim.sensing.sensors",
    "cosim.simulation.maneuver_metrics": "cosim.simulation.manoeuvre_metrics",
    "cosim.slip_control_params": "cosim.core.slip_control_params",
    "cosim.suspension_params": "cosim.core.suspension_params",
    "cosim.sweep": "cosim.sweeps",
    "cosim.sweep.driver": "cosim.sweeps.driver",
    "cosim.sweep.execute": "cosim.sweeps.execute",
    "cosim.sweep.plots": "cosim.sweeps.plots",
    "cosim.sweep.results": "cosim.sweeps.results",
    "cosim.sweep.spec": "cosim.sweeps.spec",
    "cosim.tire_model": "cosim.plant.tyre_model",
    "cosim.traffic_records": "cosim.core.traffic_records",
    "cosim.tyre_params": "cosim.core.tyre_params",
    "cosim.vehicle_params": "cosim.core.vehicle_params",
    "cosim.yaml_io": "cosim.core.yaml_io",
    "estimation.models": "estimation.process_model",
    "tracker.acc": "tracker.cruise",
    "tracker.acc.config": "tracker.cruise.config",
    "tracker.acc.esc": "tracker.cruise.esc",
    "tracker.acc.law": "tracker.cruise.law",
    "tracker.acc_config": "tracker.cruise.config",
    "tracker.delay_line": "tracker.mpc.delay_line",
    "tracker.double_lane_change": "tracker.paths.double_lane_change",
    "tracker.dynamic_bicycle": "tracker.models.dynamic_bicycle",
    "tracker.dynamic_mpc": "tracker.mpc.dynamic_mpc",
    "tracker.dynamic_mpc_config": "tracker.mpc.dynamic_mpc_config",
    "tracker.dynamic_nmpc": "tracker.mpc.dynamic_nmpc",
    "tracker.esc": "tracker.cruise.esc",
    "tracker.fallback": "tracker.mpc.fallback",
    "tracker.grip_config": "tracker.mpc.grip_config",
    "tracker.grip_speed": "tracker.mpc.grip_speed",
    "tracker.horizon_reference": "tracker.mpc.horizon_reference",
    "tracker.kinematic_bicycle": "tracker.models.kinematic_bicycle",
    "tracker.kinematic_nmpc": "tracker.mpc.kinematic_nmpc",
    "tracker.ltv_mpc": "tracker.mpc.ltv_mpc",
    "tracker.ltv_mpc_config": "tracker.mpc.ltv_mpc_config",
    "tracker.ltv_qp": "tracker.mpc.ltv_qp",
    "tracker.maneuver": "tracker.manoeuvre",
    "tracker.nmpc": "tracker.mpc.nmpc",
    "tracker.path_error_bicycle": "tracker.models.path_error_bicycle",
    "tracker.plugin": "tracker.plugins.loading",
    "tracker.plugin_checks": "tracker.plugins.checks",
    "tracker.reference_path": "tracker.paths.reference_path",
    "tracker.steered_dynamic_bicycle": "tracker.models.steered_dynamic_bicycle",
    "tracker.tyre_limits": "tracker.models.tyre_limits",
    "tracker.vector_layout": "tracker.mpc.vector_layout",
})
"""Old module name -> the module that holds its contents now."""


def moved_to(module: str) -> str | None:
    """Where ``module`` (or the package it is in) moved, or None."""
    parts = module.split(".")
    for end in range(len(parts), 0, -1):
        new = MOVED_MODULES.get(".".join(parts[:end]))
        if new is not None:
            return ".".join([new, *parts[end:]])
    return None
