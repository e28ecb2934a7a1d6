"""The records of :mod:`cosim.log.run_messages` as bytes, for ``cosim run``'s pipe.

A run's process packs each log instant, measurement and plan into one frame's payload and
the process that writes the log unpacks the same record from it (the numbers as IEEE
doubles, ``struct`` and ``ndarray.tobytes``: bit for bit; the two processes are one
machine's). What repeats (the estimate's state names, the sensors' bias and channel names)
is sent once as a *layout* and named by its number afterwards. A plan is pickled (20 a
second; its arrays, strings and flags as they are).

Records of a type other than the project's own (a plug-in's subclass) are not packed: the
run builds their messages itself (:class:`PackedMessages`' ``fallback``), in order with the
packed ones.
"""

from __future__ import annotations

import operator
import pickle
import struct
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from cosim.core.records import Estimate, Measurement, Plan, VehicleState
from cosim.log.run_messages import RunMessageSink, TrackingErrors
from estimation.update_result import UpdateResult

_TRUTH_FIELDS: tuple[str, ...] = ("t_s", "x_m", "y_m", "z_m", "roll_rad", "pitch_rad",
                                  "yaw_rad", "vx_mps", "vy_mps", "yaw_rate_radps", "ax_mps2",
                                  "ay_mps2", "steer_rad")
"""The truth's fields before its wheel speeds, in :class:`VehicleState`'s order."""
_truth_fields = operator.attrgetter(*_TRUTH_FIELDS)

_INSTANT_HEAD = struct.Struct("<IB3xddII")
"""A log instant: layout, scene flag, t_s, the estimate's t_s, its covariance's rows and
columns; then the doubles: the truth's fields and wheel speeds, the four tracking errors,
the biases, the estimate's mean, its covariance (row-major)."""
_MEASUREMENT_HEAD = struct.Struct("<IddIII")
"""A measurement: layout, the delivery's t_s, the measurement's t_s, its values' count,
its covariance's rows and columns; then the values and the covariance."""
_UPDATE = struct.Struct("<IB3xddq")
"""A filter's update: layout (sensor and reason), accepted, t_s, NIS, channels."""


@dataclass(frozen=True)
class InstantLayout:
    """What an instant's doubles are: names sent once."""

    estimate_names: tuple[str, ...]
    bias_names: tuple[str, ...]
    wheels: int


@dataclass(frozen=True)
class MeasurementLayout:
    sensor: str
    names: tuple[str, ...]


@dataclass(frozen=True)
class UpdateLayout:
    sensor: str
    reason: str


Layout = InstantLayout | MeasurementLayout | UpdateLayout


class PackedMessages:
    """A :class:`~cosim.log.run_messages.RunMessageSink` that sends each record's numbers
    through ``send(kind, payload)`` (kinds: :data:`LAYOUT`, :data:`INSTANT`,
    :data:`MEASUREMENT`, :data:`PLAN`, :data:`UPDATE`); ``fallback`` builds the messages of
    a record it does not pack (module docstring)."""

    def __init__(self, send: Callable[[int, bytes], None], fallback: RunMessageSink) -> None:
        self._send = send
        self._fallback = fallback
        self._layouts: dict[tuple[object, ...], int] = {}
        """Each layout's number, by the plain tuple of its fields (a key made faster than
        the dataclass)."""
        self._doubles: dict[int, struct.Struct] = {}

    def _layout(self, key: tuple[object, ...], make: Callable[..., Layout]) -> int:
        number = self._layouts.get(key)
        if number is None:
            number = self._layouts[key] = len(self._layouts)
            self._send(LAYOUT, pickle.dumps(make(*key), protocol=pickle.HIGHEST_PROTOCOL))
        return number

    def _pack_doubles(self, values: tuple[float, ...]) -> bytes:
        packer = self._doubles.get(len(values))
        if packer is None:
            packer = self._doubles[len(values)] = struct.Struct(f"<{len(values)}d")
        return packer.pack(*values)

    def instant(self, t_s: float, truth: VehicleState, biases: Mapping[str, float],
                estimate: Estimate, scene: bool, errors: TrackingErrors) -> None:
        covariance = estimate.covariance
        if not (type(truth) is VehicleState and type(estimate) is Estimate
                and _plain(estimate.names, estimate.mean) and _matrix(covariance)):
            self._fallback.instant(t_s, truth, biases, estimate, scene, errors)
            return
        wheels = truth.wheel_speed_radps
        layout = self._layout((estimate.names, tuple(biases), len(wheels)), InstantLayout)
        rows, columns = covariance.shape
        self._send(INSTANT, b"".join((
            _INSTANT_HEAD.pack(layout, scene, t_s, estimate.t_s, rows, columns),
            self._pack_doubles((*_truth_fields(truth), *wheels, errors.cte_m,
                                errors.heading_err_rad, errors.speed_err_mps,
                                errors.ref_speed_mps, *biases.values())),
            estimate.mean.tobytes(), covariance.tobytes())))

    def measurement(self, t_s: float, measurement: Measurement) -> None:
        values, covariance = measurement.values, measurement.covariance
        if not (type(measurement) is Measurement and _plain(measurement.names, values)
                and _matrix(covariance)):
            self._fallback.measurement(t_s, measurement)
            return
        layout = self._layout((measurement.sensor, measurement.names), MeasurementLayout)
        rows, columns = covariance.shape
        self._send(MEASUREMENT, b"".join((
            _MEASUREMENT_HEAD.pack(layout, t_s, measurement.t_s, values.size, rows, columns),
            values.tobytes(), covariance.tobytes())))

    def update(self, t_s: float, sensor: str, update: UpdateResult) -> None:
        if not (type(update) is UpdateResult and type(update.accepted) is bool
                and type(update.dim) is int):
            self._fallback.update(t_s, sensor, update)
            return
        layout = self._layout((sensor, update.reason), UpdateLayout)
        self._send(UPDATE, _UPDATE.pack(layout, update.accepted, t_s, update.nis, update.dim))

    def plan(self, t_s: float, plan: Plan) -> None:
        if type(plan) is not Plan:
            self._fallback.plan(t_s, plan)
            return
        self._send(PLAN, struct.pack("<d", t_s)
                   + pickle.dumps(plan, protocol=pickle.HIGHEST_PROTOCOL))


def _plain(names: object, values: object) -> bool:
    """Names a tuple and values a vector of doubles (what the project's own components
    give): a record packed and unpacked then builds the same message."""
    return (type(names) is tuple and isinstance(values, np.ndarray) and values.ndim == 1
            and values.dtype == np.float64)


def _matrix(values: object) -> bool:
    """A matrix of doubles (``tobytes`` gives its rows in order, whatever its strides)."""
    return isinstance(values, np.ndarray) and values.ndim == 2 and values.dtype == np.float64


LAYOUT, INSTANT, MEASUREMENT, PLAN, UPDATE = range(5)
"""The kinds of packed payload (:meth:`PackedReader.apply` takes each)."""


class PackedReader:
    """Unpacks what a :class:`PackedMessages` sent and hands the records to ``sink``."""

    def __init__(self, sink: RunMessageSink) -> None:
        self._sink = sink
        self._layouts: list[Layout] = []

    def apply(self, kind: int, payload: bytes) -> None:
        if kind == INSTANT:
            self._instant(payload)
        elif kind == MEASUREMENT:
            self._measurement(payload)
        elif kind == PLAN:
            (t_s,) = struct.unpack_from("<d", payload)
            self._sink.plan(t_s, pickle.loads(payload[8:]))
        elif kind == UPDATE:
            number, accepted, t_s, nis, dim = _UPDATE.unpack(payload)
            layout = self._layouts[number]
            assert isinstance(layout, UpdateLayout)
            self._sink.update(t_s, layout.sensor,
                              UpdateResult(bool(accepted), nis, dim, layout.reason))
        elif kind == LAYOUT:
            layout = pickle.loads(payload)
            if not isinstance(layout, InstantLayout | MeasurementLayout | UpdateLayout):
                raise ValueError(f"a packed record's layout of type {type(layout).__name__}")
            self._layouts.append(layout)
        else:
            raise ValueError(f"a packed record of kind {kind}: expected 0-4")

    def _instant(self, payload: bytes) -> None:
        number, scene, t_s, estimate_t_s, rows, columns = _INSTANT_HEAD.unpack_from(payload)
        layout = self._layouts[number]
        assert isinstance(layout, InstantLayout)
        doubles = np.frombuffer(payload, dtype=float, offset=_INSTANT_HEAD.size)
        n_truth = len(_TRUTH_FIELDS) + layout.wheels
        n_plain = n_truth + 4 + len(layout.bias_names)
        plain = doubles[:n_plain].tolist()
        n_states = len(layout.estimate_names)
        truth = VehicleState(*plain[:len(_TRUTH_FIELDS)],
                             tuple(plain[len(_TRUTH_FIELDS):n_truth]))
        errors = TrackingErrors(*plain[n_truth:n_truth + 4])
        biases = dict(zip(layout.bias_names, plain[n_truth + 4:], strict=True))
        estimate = Estimate(estimate_t_s, layout.estimate_names,
                            doubles[n_plain:n_plain + n_states],
                            doubles[n_plain + n_states:].reshape(rows, columns))
        self._sink.instant(t_s, truth, biases, estimate, bool(scene), errors)

    def _measurement(self, payload: bytes) -> None:
        number, t_s, measured_t_s, size, rows, columns = _MEASUREMENT_HEAD.unpack_from(payload)
        layout = self._layouts[number]
        assert isinstance(layout, MeasurementLayout)
        doubles = np.frombuffer(payload, dtype=float, offset=_MEASUREMENT_HEAD.size)
        self._sink.measurement(t_s, Measurement(layout.sensor, measured_t_s, layout.names,
                                                doubles[:size],
                                                doubles[size:].reshape(rows, columns)))
