"""A builder run once per process gives the kept result for exactly equal arguments only."""

from __future__ import annotations

from dataclasses import dataclass

from cosim.core.built_once import KEPT, built_once


@dataclass(frozen=True)
class _Numbers:
    mass_kg: float
    name: str = "sedan"


def test_equal_arguments_share_one_result_and_others_get_their_own() -> None:
    calls: list[_Numbers] = []

    @built_once
    def build(numbers: _Numbers, scale: float = 1.0) -> list[float]:
        calls.append(numbers)
        return [numbers.mass_kg * scale]

    first = build(_Numbers(1500.0))
    assert build(_Numbers(1500.0)) is first and len(calls) == 1
    assert build(_Numbers(1600.0)) == [1600.0] and len(calls) == 2
    assert build(_Numbers(1500.0), scale=2.0) == [3000.0] and len(calls) == 3


def test_zero_and_negative_zero_are_built_apart() -> None:
    @built_once
    def build(value: float) -> float:
        return value

    assert 0.0 == -0.0
    assert str(build(0.0)) == "0.0"
    assert str(build(-0.0)) == "-0.0"  # not the kept 0.0: a run never depends on another


def test_a_few_results_are_kept() -> None:
    calls: list[int] = []

    @built_once
    def build(value: int) -> int:
        calls.append(value)
        return value

    for value in range(KEPT + 1):
        build(value)
    build(KEPT)  # kept
    build(0)  # the least recently used went first
    assert calls == [*range(KEPT + 1), 0]
