"""Traffic checked against the ego car and the ACC's sensor before a run starts.

A scenario's ``traffic:`` cars are validated one by one by :func:`cosim.plant.traffic.traffic_cars`;
what only makes sense with the rest of the configuration is checked here, so that a set-up
that cannot work is one line and exit code 2 instead of a run that ends badly at once:

- the ACC (``tracker.acc.enabled``) sees the car ahead only through the range sensor, so
  ``sensors.radar.enabled`` must be true (without it the ACC drives into the lead car);
- no car may start overlapping the ego's body (it would be a ``collision`` at t = 0): the
  ego's body box (:func:`cosim.plant.sedan_model.body_box_m`, from the plant's wheelbase
  and track) and the car's (the ``shell`` box of ``models/lead_car.xml``) are compared in
  the lane frame the cars' scripts use (origin at the ego's initial CoG, x along its
  initial heading).
"""

from __future__ import annotations

import functools
import xml.etree.ElementTree as ElementTree
from typing import TYPE_CHECKING

from cosim.core.exceptions import ConfigError
from cosim.plant.sedan_model import body_box_m, lead_car_xml_path
from cosim.plant.traffic import TRAFFIC_BODY_GEOM, traffic_cars

if TYPE_CHECKING:
    from cosim.simulation.scenario_config import ScenarioConfig


@functools.cache
def traffic_car_half_size_m() -> tuple[float, float]:
    """Half length and half width of a traffic car's body box (``models/lead_car.xml``)."""
    root = ElementTree.parse(lead_car_xml_path()).getroot()
    shell = next(g for g in root.iter("geom") if g.get("name") == TRAFFIC_BODY_GEOM)
    half_length, half_width, _ = (float(v) for v in (shell.get("size") or "").split())
    return half_length, half_width


def check_traffic(config: ScenarioConfig) -> None:
    """Refuse traffic the ego or its ACC cannot meet (module docstring)."""
    cars = traffic_cars(config.traffic)
    acc = config.tracker.acc
    if acc.enabled and not cars:
        raise ConfigError("tracker.acc.enabled = true: expected a scenario with traffic "
                          "(a traffic: section naming at least one car)")
    if acc.enabled and not config.sensors.radar.enabled:
        raise ConfigError("sensors.radar.enabled = false: tracker.acc.enabled = true sees "
                          "the car ahead only through the radar: expected "
                          "sensors.radar.enabled=true (or tracker.acc.enabled=false)")
    centre_m, ego_half_length_m, ego_half_width_m = body_box_m(config.plant)
    car_half_length_m, car_half_width_m = traffic_car_half_size_m()
    reach_x = ego_half_length_m + car_half_length_m
    reach_y = ego_half_width_m + car_half_width_m
    for name, car in cars:
        if abs(car.gap_m - centre_m) < reach_x and abs(car.lateral_offset_m) < reach_y:
            raise ConfigError(
                f"traffic.{name}: gap_m = {car.gap_m:g}, lateral_offset_m = "
                f"{car.lateral_offset_m:g}: the car starts inside the ego's body: expected "
                f"gap_m beyond {centre_m + reach_x:.2f} (or below "
                f"{centre_m - reach_x:.2f}) or |lateral_offset_m| >= {reach_y:.2f} m")
