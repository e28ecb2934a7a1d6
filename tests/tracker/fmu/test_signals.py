"""What cosim hands an FMU: each signal checked against geometry a reader can redo by hand."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from cosim.core.records import Estimate
from tracker.fmu.signals import (
    INPUTS,
    OUTPUTS,
    InputFeed,
    implied_unit,
    markdown_table,
    parse_input,
)
from tracker.fmu.units import parse_unit, unit_disagrees
from tracker.paths.reference_path import ReferencePath

DOCS = Path(__file__).resolve().parents[3] / "docs" / "fmu.md"


def estimate(**states: float) -> Estimate:
    names = tuple(states)
    return Estimate(0.0, names, np.array([states[n] for n in names]), np.eye(len(names)))


def straight_path() -> ReferencePath:
    """Along +x from the origin, 20 m/s."""
    x = np.linspace(0.0, 200.0, 101)
    return ReferencePath(x, np.zeros_like(x), 20.0)


def circle_path(radius_m: float) -> ReferencePath:
    """Counter-clockwise (turning left) around the origin, closed."""
    angle = np.linspace(0.0, 2.0 * np.pi, 400, endpoint=False)
    return ReferencePath(radius_m * np.cos(angle), radius_m * np.sin(angle), 10.0, closed=True)


def test_path_signals_of_a_car_left_of_a_straight_path() -> None:
    names = ("cte_m", "heading_err_rad", "speed_mps", "ref_speed_mps", "curvature_1pm",
             "path_s_m", "est_vy_mps")
    feed = InputFeed(names, preview_spacing_m=2.0)
    values = feed.values(0.0, estimate(x_m=50.0, y_m=1.0, yaw_rad=0.1, vx_mps=20.0,
                                       vy_mps=1.0), straight_path())
    expected = [1.0, 0.1, math.hypot(20.0, 1.0), 20.0, 0.0, 50.0, 1.0]
    np.testing.assert_allclose(values, expected, atol=1e-9)


def test_a_car_inside_a_left_turn_is_left_of_the_path() -> None:
    radius = 40.0
    feed = InputFeed(("cte_m", "curvature_1pm", "heading_err_rad"), 2.0)
    # On the positive x axis, 0.5 m inside the circle, heading along the path (+y).
    values = feed.values(0.0, estimate(x_m=radius - 0.5, y_m=0.0, yaw_rad=math.pi / 2,
                                       vx_mps=10.0), circle_path(radius))
    np.testing.assert_allclose(values, [0.5, 1.0 / radius, 0.0], atol=1e-4)


def test_preview_points_turned_back_to_the_world_lie_on_the_path_ahead() -> None:
    spacing, count = 2.5, 8
    names = tuple(f"preview_{axis}_m[{i}]" for i in range(1, count + 1) for axis in "xy")
    car = {"x_m": 30.0, "y_m": -0.7, "yaw_rad": 0.3, "vx_mps": 15.0}
    values = InputFeed(names, spacing).values(0.0, estimate(**car), straight_path())
    x_v, y_v = np.array(values[0::2]), np.array(values[1::2])
    cos, sin = math.cos(car["yaw_rad"]), math.sin(car["yaw_rad"])
    world_x = car["x_m"] + cos * x_v - sin * y_v  # vehicle frame -> world (ENU)
    world_y = car["y_m"] + sin * x_v + cos * y_v
    np.testing.assert_allclose(world_y, 0.0, atol=1e-9)
    np.testing.assert_allclose(world_x, car["x_m"] + spacing * np.arange(1, count + 1),
                               atol=1e-9)


def test_inputs_come_in_the_order_of_the_names_given() -> None:
    car = estimate(x_m=10.0, y_m=0.2, yaw_rad=0.0, vx_mps=5.0)
    names = ("est_vx_mps", "preview_y_m[3]", "cte_m", "preview_x_m[1]")
    values = InputFeed(names, 1.0).values(0.0, car, straight_path())
    np.testing.assert_allclose(values, [5.0, -0.2, 0.2, 1.0], atol=1e-9)


def test_preview_wraps_across_the_start_line_of_a_closed_path() -> None:
    radius = 20.0
    path = circle_path(radius)
    car = estimate(x_m=radius, y_m=-1e-3, yaw_rad=math.pi / 2, vx_mps=10.0)  # just before
    x_v, y_v = InputFeed(("preview_x_m[1]", "preview_y_m[1]"), 5.0).values(0.0, car, path)
    angle = 5.0 / radius  # 5 m further along the circle, past the start line
    np.testing.assert_allclose([x_v, y_v], [radius * math.sin(angle),
                                            radius * (1.0 - math.cos(angle))], atol=2e-3)


@pytest.mark.parametrize(("name", "kind", "key", "index"), [
    ("cte_m", "path", "cte_m", 0), ("est_yaw_rate_radps", "state", "yaw_rate_radps", 0),
    ("preview_x_m[12]", "preview_x", "", 12), ("preview_y_m[1]", "preview_y", "", 1),
])
def test_input_names_parse(name: str, kind: str, key: str, index: int) -> None:
    ref = parse_input(name)
    assert ref is not None and (ref.kind, ref.key, ref.index) == (kind, key, index)


@pytest.mark.parametrize("name", ["wind_mps", "est_", "preview_z_m[1]", "preview_x_m[a]",
                                  "preview_x_m", "steer_rad"])
def test_names_cosim_does_not_serve(name: str) -> None:
    assert parse_input(name) is None


def test_units_implied_by_names() -> None:
    assert [implied_unit(n) for n in ("cte_m", "preview_y_m[4]", "est_yaw_rate_radps",
                                      "accel_mps2", "curvature_1pm", "est_wheel_track_scale")] \
        == ["m", "m", "rad/s", "m/s^2", "1/m", "-"]


@pytest.mark.parametrize(("text", "exponents"), [
    ("m/s2", {"m": 1, "s": -2}), ("m.s-2", {"m": 1, "s": -2}), ("m/s^2", {"m": 1, "s": -2}),
    ("rad/s", {"rad": 1, "s": -1}), ("1/m", {"m": -1}), ("m-1", {"m": -1}), ("1", {}),
    ("deg", None), ("km/h", None), ("m/s/s", None),
])
def test_unit_expressions(text: str, exponents: dict[str, int] | None) -> None:
    assert parse_unit(text) == exponents


class _Base:
    def __init__(self, factor: float = 1.0, **exponents: int) -> None:
        self.factor, self.offset = factor, 0.0
        for symbol in ("kg", "m", "s", "A", "K", "mol", "cd", "rad"):
            setattr(self, symbol, exponents.get(symbol, 0))


class _Unit:
    def __init__(self, base: _Base) -> None:
        self.baseUnit = base


def test_declared_units_against_implied_ones() -> None:
    definitions = {"deg": _Unit(_Base(math.pi / 180.0, rad=1)), "mps": _Unit(_Base(m=1, s=-1))}
    assert unit_disagrees(None, "m", {}) == ""
    assert unit_disagrees("m.s-2", "m/s^2", {}) == ""
    assert unit_disagrees("mps", "m/s", definitions) == ""  # its BaseUnit says m/s
    assert "expected m/s" in unit_disagrees("m", "m/s", {})
    assert "0.0174533 x base units" in unit_disagrees("deg", "rad", definitions)


def test_the_documented_table_is_the_registry() -> None:
    table = markdown_table()
    assert table in DOCS.read_text()
    assert all(f"`{s.name}`" in table for s in (*INPUTS, *OUTPUTS))


def test_the_documented_state_inputs_are_the_filters_states() -> None:
    from estimation.state import STATE_NAMES

    listed = DOCS.read_text().split("default filter (`ekf`, and `ukf`) are\n`", 1)[1]
    listed = listed.split("`.", 1)[0]
    assert [n.strip() for n in listed.replace("\n", " ").split(",")] == \
        [f"est_{name}" for name in STATE_NAMES]
