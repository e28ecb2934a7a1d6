"""The figures drawn on two cores (:mod:`cosim.plots.drawing`): every other one by a forked
process, the results in order; a figure that fails there fails here, with its exception;
a forked process that dies is one clear error."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from cosim.core.exceptions import CosimError
from cosim.plots.drawing import cores, draw


def _where(index: int) -> Path:
    """A job's result: which process drew it."""
    return Path(f"{index}-{os.getpid()}")


def _jobs(count: int) -> list:
    return [lambda i=i: _where(i) for i in range(count)]


@pytest.mark.skipif(cores() < 2, reason="one core: every figure is drawn here")
def test_every_other_figure_is_drawn_by_a_second_process_in_order() -> None:
    results = draw(_jobs(7))
    assert [int(str(p).split("-")[0]) for p in results] == list(range(7))
    drawers = [int(str(p).split("-")[1]) for p in results]
    assert set(drawers[1::2]) == {os.getpid()}
    assert len(set(drawers[0::2])) == 1 and drawers[0] != os.getpid()


def test_one_process_draws_everything_itself() -> None:
    results = draw(_jobs(5), processes=1)
    assert [str(p) for p in results] == [f"{i}-{os.getpid()}" for i in range(5)]


@pytest.mark.skipif(cores() < 2, reason="one core: every figure is drawn here")
def test_a_figure_that_fails_in_the_other_process_raises_its_exception_here() -> None:
    def bad() -> Path:
        raise ValueError("no such topic: /vehicle/truth")

    drawn: list[int] = []
    jobs = [bad, lambda: drawn.append(1) or Path("ours")]
    with pytest.raises(ValueError, match="no such topic"):
        draw(jobs)
    assert drawn == [1]  # this process's own figures were drawn meanwhile


@pytest.mark.skipif(cores() < 2, reason="one core: every figure is drawn here")
def test_a_drawing_process_that_dies_is_one_clear_error() -> None:
    def dies() -> Path:
        os._exit(3)

    with pytest.raises(CosimError, match=r"died \(exit code 3\)"):
        draw([dies, lambda: Path("ours")])
