"""The plant builds and drives over the whole (CoG height, wheel radius) grid of the
mismatch example: a tyre contact inside MuJoCo's margin but outside the constraint set
(``efc_address`` -1) used to be read at ``efc_force[-1]`` and failed while settling."""

from __future__ import annotations

import dataclasses

import pytest

from cosim.core.initial_state import InitialState
from cosim.core.records import ActuatorCommand
from cosim.core.vehicle_params import PlantConfig
from cosim.plant.car import MujocoPlant
from cosim.sweeps.spec import load_spec

DT_S = 0.002
GRAVITY_MPS2 = 9.81


@pytest.mark.parametrize(("cog_height_m", "wheel_radius_m"),
                         [(0.45, 0.28), (0.60, 0.28), (0.65, 0.28), (0.60, 0.36),
                          (0.65, 0.36), (0.45, 0.36)])
def test_corner_of_the_grid_builds_settles_and_drives(cog_height_m: float,
                                                       wheel_radius_m: float) -> None:
    config = dataclasses.replace(PlantConfig(), cog_height_m=cog_height_m,
                                 wheel_radius_m=wheel_radius_m)
    plant = MujocoPlant(config, DT_S, InitialState(speed_mps=15.0))
    plant.apply(ActuatorCommand(t_s=0.0, steer_rad=0.02, drive_torque_nm=0.0,
                                brake_torque_nm=0.0))
    for _ in range(250):  # half a second
        plant.advance()
    state = plant.state()
    assert 14.0 < state.vx_mps < 15.5
    loads = [tyre.load_n for tyre in plant.tyre_forces()]
    # The four tyres carry the car (within the suspension's transient and the cornering).
    assert sum(loads) == pytest.approx(config.mass_kg * GRAVITY_MPS2, rel=0.1)
    assert min(loads) > 0.0


def test_the_example_sweep_spans_the_grid() -> None:
    spec = load_spec("examples/cog-wheel-radius.yaml")
    values = {p.path: p.values for p in spec.parameters}
    assert min(values["plant.cog_height_m"]) == 0.45
    assert max(values["plant.cog_height_m"]) == 0.65
    assert (min(values["plant.wheel_radius_m"]), max(values["plant.wheel_radius_m"])) \
        == (0.28, 0.36)
    assert spec.n_runs == 15
