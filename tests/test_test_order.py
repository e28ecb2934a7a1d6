"""The order pytest-xdist's workers take the tests in (``tests/conftest.py``)."""

from __future__ import annotations

from dataclasses import dataclass

from tests.conftest import balanced_order


@dataclass(frozen=True)
class _Item:
    nodeid: str
    slow: bool

    def get_closest_marker(self, name: str) -> object | None:
        return object() if name == "slow" and self.slow else None


def _module(name: str, slow: int, fast: int) -> list[_Item]:
    return ([_Item(f"{name}.py::slow{i}", True) for i in range(slow)]
            + [_Item(f"{name}.py::fast{i}", False) for i in range(fast)])


def test_each_workers_share_starts_with_slow_modules_and_keeps_them_whole() -> None:
    items = (_module("a", 0, 30) + _module("b", 2, 3) + _module("c", 0, 20)
             + _module("d", 5, 1) + _module("e", 1, 0) + _module("f", 0, 10))
    ordered = balanced_order(items, 2)
    assert sorted(i.nodeid for i in ordered) == sorted(i.nodeid for i in items)
    half = len(items) // 2  # the scheduler's first share
    first, second = ordered[:half], ordered[half:]
    # the most slow tests (d) to one share, the next (b, then e) to the other
    assert [i.nodeid.partition(".")[0] for i in first[:6]] == ["d"] * 6
    assert [i.nodeid.partition(".")[0] for i in second[:6]] == ["b"] * 5 + ["e"]
    # every slow test starts before any module without one, in both shares
    for share in (first, second):
        kinds = [any(j.slow for j in items if j.nodeid.partition("::")[0]
                     == i.nodeid.partition("::")[0]) for i in share]
        assert kinds == sorted(kinds, reverse=True)
    # the modules without slow tests follow in their order
    light = [i for i in ordered if i.nodeid[0] in "acf"]
    assert light == [i for i in items if i.nodeid[0] in "acf"]
