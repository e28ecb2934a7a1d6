"""Physics conformance: the plant against the dynamic bicycle identified from it.

The linear-tyre dynamic bicycle (Rajamani 2012, sec. 2.3) identified by
:func:`cosim.identification.identify` must predict the plant's steady-state yaw-rate gain
r/delta in the linear range, and a passenger sedan understeers mildly: production cars
lie between about 0.5 and 4 deg/g (Gillespie, "Fundamentals of Vehicle Dynamics", ch. 6;
Rajamani, "Vehicle Dynamics and Control", ch. 3). The MathWorks example's tyres
(C_f = 19000 N/rad, C_r = 33000 N/rad) give 15 deg/g, far beyond that range; the plant is
not tuned to them.

Numbers a reader can check: a neutral car (K = 0) of wheelbase 2.8 m has r/delta = v / L
= 3.57, 7.14 and 10.71 1/s at 10, 20 and 30 m/s; with K = 2 deg/g = 0.00356 rad/(m/s^2)
these fall to v / (L + K v^2) = 3.17, 4.74 and 5.00 1/s.
"""

from __future__ import annotations

import pytest

from cosim.core.vehicle_params import PlantConfig, VehicleParams
from cosim.identification import IdentifiedModel, identify
from cosim.identification.manoeuvres import Rig, steady_turn

pytestmark = pytest.mark.conformance

DT_S = 0.002
NOMINAL = PlantConfig()
LATERAL_ACCEL_MPS2 = 0.25 * 9.81
"""The check drives at a quarter g, inside the tyres' linear range."""

pytestmark = pytest.mark.slow  # identifying the plant takes seconds


@pytest.fixture(scope="module")
def identified() -> IdentifiedModel:
    return identify(NOMINAL, VehicleParams(), DT_S)


@pytest.mark.parametrize("speed_mps", [10.0, 20.0, 30.0])
def test_steady_yaw_rate_gain_matches_the_identified_bicycle(identified: IdentifiedModel,
                                                             speed_mps: float) -> None:
    # Steer for a quarter g by the identified model itself: delta = (L / v^2 + K) a_y.
    steer = LATERAL_ACCEL_MPS2 * (identified.cog_front_m + identified.cog_rear_m) / speed_mps**2
    steer += LATERAL_ACCEL_MPS2 * identified.understeer_gradient_radpmps2
    turn = steady_turn(Rig(NOMINAL, VehicleParams(), DT_S), speed_mps, steer)
    assert turn.yaw_rate_gain_per_s == pytest.approx(identified.yaw_rate_gain_per_s(speed_mps),
                                                     rel=0.10)


def test_default_sedan_understeers_by_half_to_four_deg_per_g(
        identified: IdentifiedModel) -> None:
    # The default tyres are the Magic Formula ones (plant.tyre_model = pacejka); MuJoCo's
    # contact tyres (plant.tyre_model = contact) are nearly neutral, about 0.03 deg/g.
    assert 0.5 <= identified.understeer_gradient_degpg <= 4.0
