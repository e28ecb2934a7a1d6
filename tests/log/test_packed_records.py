"""The run's most frequent records sent as numbers (:mod:`cosim.log.packed_records`) give
the messages the run would have built itself (:mod:`cosim.log.run_messages`), and a whole
run's log written through ``cosim run``'s pipe holds the messages of one written in-process."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from mcap.reader import make_reader

from cosim.core.records import Estimate, Measurement, Plan, VehicleState
from cosim.core.vehicle_params import CarParams
from cosim.log import topics
from cosim.log.foxglove import GeoOrigin
from cosim.log.packed_records import PackedMessages, PackedReader
from cosim.log.recorder import encode_message
from cosim.log.run_messages import MessageContext, RunMessages, TrackingErrors
from cosim.simulation.runner import run
from cosim.simulation.scenario_config import load_config
from estimation.update_result import REASONS, UpdateResult
from tests.log.test_piped_recorder import _served

CONTEXT = MessageContext(CarParams(), 0.02, GeoOrigin())


class Writes:
    """A recorder's writing side that keeps what it is given, encoded as the log encodes."""

    def __init__(self) -> None:
        self.records: list[tuple[str, Any, ...]] = []

    def register(self, topic: str, schema: object = None) -> None:
        self.records.append(("register", topic))

    def write(self, topic: str, t_s: float, message: dict[str, Any]) -> None:
        self.records.append((topic, t_s, encode_message(message)))

    write_finite = write


def _records(rng: np.random.Generator) -> list[tuple[str, tuple[Any, ...]]]:
    """A run's worth of varied records: NaN and infinities, a GNSS fix with and without a
    finite position, two estimate layouts, updates with every reason, plans with and
    without world positions."""
    names = ("x_m", "y_m", "yaw_rad", "vx_mps")
    calls: list[tuple[str, tuple[Any, ...]]] = []
    for k in range(40):
        t_s = 0.01 * k
        truth = VehicleState(t_s, *rng.normal(size=12).tolist(), tuple(rng.normal(size=4)))
        covariance = rng.normal(size=(4, 4))
        covariance = covariance @ covariance.T
        if k == 7:
            covariance[0, 1] = math.nan
        estimate = Estimate(t_s - 0.001 * (k % 2), names if k < 30 else names[:3],
                            rng.normal(size=4 if k < 30 else 3),
                            covariance if k < 30 else covariance[:3, :3])
        errors = TrackingErrors(*rng.normal(size=3).tolist(), math.inf if k == 5 else 20.0)
        biases = {"gyro_bias_radps": float(rng.normal()), "accel_bias_mps2": -0.01 * k}
        calls.append(("instant", (t_s, truth, biases, estimate, k % 4 == 0, errors)))
        position = rng.normal(size=2)
        if k == 11:
            position[1] = math.nan
        calls.append(("measurement", (t_s, Measurement("gnss", t_s - 0.05, ("x_m", "y_m"),
                                                       position, np.eye(2) * 4e-4))))
        calls.append(("measurement", (t_s, Measurement(
            "imu", t_s, ("ax_mps2", "ay_mps2", "yaw_rate_radps"), rng.normal(size=3),
            np.diag([0.1, 0.1, math.nan if k == 3 else 0.01])))))
        calls.append(("update", (t_s, "imu", UpdateResult(
            k % 3 != 0, math.nan if k % 7 == 0 else float(rng.chisquare(3)), 3,
            REASONS[k % len(REASONS)]))))
        if k % 5 == 0:
            world = k % 10 == 0
            state_names = ("x_m", "y_m", "vx_mps") if world else ("e1_m", "vx_mps")
            states = rng.normal(size=(6, len(state_names)))
            calls.append(("plan", (t_s, Plan(t_s, 0.1, state_names, states,
                                              ("accel_mps2", "steer_rad"),
                                              rng.normal(size=(5, 2)), float(rng.normal()),
                                              1e-3, k, "Solve_Succeeded", True, False))))
    return calls


def _through(sink: Any, calls: list[tuple[str, tuple[Any, ...]]]) -> None:
    for method, arguments in calls:
        getattr(sink, method)(*arguments)


def _packed_then_built(calls: list[tuple[str, tuple[Any, ...]]]) -> tuple[Writes, Writes]:
    """The messages built in the run (``fallback``) and in the server, from packed bytes."""
    served, fallback = Writes(), Writes()
    reader = PackedReader(RunMessages(served, CONTEXT))
    _through(PackedMessages(lambda kind, payload: reader.apply(kind, bytes(payload)),
                            RunMessages(fallback, CONTEXT)), calls)
    return served, fallback


def test_packed_records_build_the_messages_the_run_would_build() -> None:
    """Every message equal, byte for byte, and in the same order, ``/scene/plan``
    registered with its first message; nothing falls back to the run."""
    calls = _records(np.random.default_rng(5))
    own = Writes()
    _through(RunMessages(own, CONTEXT), calls)
    served, fallback = _packed_then_built(calls)
    assert served.records == own.records
    assert fallback.records == []
    assert [r for r in own.records if r[0] == "register"] == [("register", topics.SCENE_PLAN)]
    assert sum(r[0] == topics.GNSS_FIX for r in own.records) == 39  # one position NaN
    assert sum(r[0] == topics.SCENE_CAR for r in own.records) == 10


def test_a_changed_number_changes_the_message() -> None:
    """The comparison above sees one double changed in the packed bytes (the test fails on
    a codec that drops or moves a field)."""
    calls = _records(np.random.default_rng(5))[:1]
    own = Writes()
    _through(RunMessages(own, CONTEXT), calls)
    served = Writes()
    reader = PackedReader(RunMessages(served, CONTEXT))

    def corrupt(kind: int, payload: bytes) -> None:
        data = bytearray(payload)
        if len(data) > 200:  # an instant: one byte of the truth's x_m
            data[32 + 8 + 3] ^= 0x10
        reader.apply(kind, bytes(data))

    _through(PackedMessages(corrupt, RunMessages(Writes(), CONTEXT)), calls)
    assert served.records != own.records
    truth = json.loads(served.records[0][2])
    assert truth["x_m"] != json.loads(own.records[0][2])["x_m"]
    assert truth["y_m"] == json.loads(own.records[0][2])["y_m"]


def test_records_the_codec_does_not_know_are_built_in_the_run() -> None:
    """A plug-in's subclass of a record, or a mean that is not a vector, is not packed:
    the run builds its messages (in order with the rest), the same messages."""

    @dataclasses.dataclass(frozen=True)
    class OwnPlan(Plan):
        pass

    calls = _records(np.random.default_rng(9))[:8]
    t_s, plan = 0.0, next(a[1] for m, a in calls if m == "plan")
    own_plan = OwnPlan(**{f.name: getattr(plan, f.name) for f in dataclasses.fields(Plan)})
    instant = [a for m, a in calls if m == "instant"][1]  # no scene: it reads the mean
    assert not instant[4]
    column = dataclasses.replace(instant[3], mean=instant[3].mean.reshape(-1, 1))
    odd = [("plan", (t_s, own_plan)), ("instant", (*instant[:3], column, *instant[4:]))]
    served, fallback = _packed_then_built(odd)
    own = Writes()
    _through(RunMessages(own, CONTEXT), odd)
    assert served.records == []
    assert fallback.records == own.records


def _messages(path: Path) -> list[tuple[str, int, bytes]]:
    """Every message but those that carry wall-clock time (the solve's and the run's)."""
    out = []
    with path.open("rb") as file:
        for _, channel, message in make_reader(file).iter_messages(log_time_order=False):
            if channel.topic in (topics.METRICS, topics.METRICS_LIVE):
                continue
            data = message.data
            if channel.topic == topics.CONTROL_PLAN:
                plan = json.loads(data)
                plan.pop("solve_time_s")
                data = json.dumps(plan).encode()
            out.append((channel.topic, message.log_time, data))
    return out


@pytest.mark.parametrize("overrides", [["sensors.suite=gnss"], ["tracker.name=dynamic-mpc"]])
def test_a_run_logged_through_the_pipe_holds_the_messages_of_one_logged_in_process(
        tmp_path: Path, overrides: list[str]) -> None:
    """The same run (GNSS fixes and plans with world positions; a tracker whose plans have
    none) through :class:`PipedRecorder` to a server and through the run's own recorder:
    the same messages in the same order, the same channels."""
    config = load_config("lane-change", duration_s=2.0, overrides=overrides)
    own, served = tmp_path / "own.mcap", tmp_path / "served.mcap"
    run(config, own)
    with _served() as (link, _):
        run(config, served, log_link=link)
    assert _messages(served) == _messages(own)
    with own.open("rb") as a, served.open("rb") as b:
        channels = [[c.topic for c in make_reader(f).get_summary().channels.values()]
                    for f in (a, b)]
    assert channels[0] == channels[1]
