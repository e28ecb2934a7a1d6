"""Conformance in a straight line: the acceleration demand through the low-level layer.

:class:`cosim.plant.low_level.AccelToTorque` turns a demand into wheel torque with a belief about
the car (Gillespie 1992, ch. 2 and 4): ``T = R (m_eff a + 1/2 rho C_d A v^2 + C_rr m g)``,
``m_eff = m + 4 I_w / R^2``. With the nominal belief the plant achieves the demand; with
a belief 20 % lighter (m = 1260 kg, m_eff = 1260 + 41.6 = 1301.6 kg, rolling resistance
0.012 * 1260 * 9.81 = 148.3 N instead of 185.4 N) the true car (m_eff = 1616.6 kg) gets

    a = (1301.6 a_cmd + 148.3 - 185.4) / 1616.6

that is 1.587 m/s^2 for +2 and -3.244 m/s^2 for -4 m/s^2: about 1301.6 / 1616.6 = 0.805
of the demand.
"""

from __future__ import annotations

import pytest

from cosim.core.vehicle_params import PlantConfig, VehicleParams
from tests.conformance.driving import constant_accel, drive, plant_at

pytestmark = pytest.mark.conformance

TYRE_MODELS = ("pacejka", "contact")
WINDOW_S = (1.0, 3.0)
"""Acceleration measured as the speed change over this window, after the transient."""


def achieved_accel_mps2(config: PlantConfig, belief: VehicleParams, demand_mps2: float) -> float:
    states = drive(plant_at(20.0, config), WINDOW_S[1], constant_accel(belief, demand_mps2))
    start = next(s for s in states if s.t_s >= WINDOW_S[0] - 1e-9)
    end = states[-1]
    return (end.vx_mps - start.vx_mps) / (end.t_s - start.t_s)


@pytest.mark.parametrize("tyre_model", TYRE_MODELS)
@pytest.mark.parametrize("demand_mps2", [2.0, -4.0])
def test_nominal_belief_achieves_the_demand(tyre_model: str, demand_mps2: float) -> None:
    config = PlantConfig(tyre_model=tyre_model)
    achieved = achieved_accel_mps2(config, config, demand_mps2)
    assert achieved == pytest.approx(demand_mps2, rel=0.10)


@pytest.mark.parametrize("tyre_model", TYRE_MODELS)
@pytest.mark.parametrize(("demand_mps2", "expected_mps2"), [(2.0, 1.587), (-4.0, -3.244)])
def test_belief_20_percent_light_falls_short_by_the_mass_ratio(
        tyre_model: str, demand_mps2: float, expected_mps2: float) -> None:
    config = PlantConfig(tyre_model=tyre_model)
    light = VehicleParams(mass_kg=0.8 * config.mass_kg)
    achieved = achieved_accel_mps2(config, light, demand_mps2)
    assert achieved == pytest.approx(expected_mps2, rel=0.05)
    assert achieved / demand_mps2 == pytest.approx(1301.6 / 1616.6, abs=0.03)
