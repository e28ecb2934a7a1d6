"""Every built-in tracker implements :class:`tracker.protocol.Tracker`; the optional
capabilities (:class:`~tracker.protocol.Resettable`, :class:`~tracker.protocol.RangeObserver`)
are found by ``isinstance`` exactly on the trackers that have them."""

from __future__ import annotations

import pytest

from cosim.core.plugins import missing_members
from tracker.config import TrackerConfig
from tracker.protocol import RangeObserver, Resettable, Tracker
from tracker.registry import TRACKER_NAMES, make_tracker


@pytest.mark.parametrize("name", TRACKER_NAMES)
def test_built_in_trackers_implement_the_protocol(name: str) -> None:
    tracker = make_tracker(TrackerConfig(name=name))
    assert isinstance(tracker, Tracker)
    assert isinstance(tracker, Resettable)
    assert not isinstance(tracker, RangeObserver)


def test_the_acc_observes_the_range_sensor() -> None:
    from cosim.core.config_fields import from_dict

    config = from_dict(TrackerConfig, {"name": "pid", "acc": {"enabled": True}}, "tracker")
    tracker = make_tracker(config)
    assert isinstance(tracker, RangeObserver)
    assert isinstance(tracker, Resettable)


def test_a_class_without_step_is_no_tracker() -> None:
    class Stepless:
        def reset(self) -> None: ...

    assert not isinstance(Stepless(), Tracker)
    assert isinstance(Stepless(), Resettable)
    assert missing_members(Stepless, Tracker) == ["step"]
