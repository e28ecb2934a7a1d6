"""The sensors' measurement models ``z = h(x) + v`` of the filters, built symbolically with
CasADi over the state of :mod:`estimation.state` (the tyre and kinematic terms from
   :mod:`estimation.process_model`).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import ParamSpec

import casadi as ca
import numpy as np

from cosim.core.built_once import built_once
from cosim.core.dense_function import DenseFunction
from cosim.core.records import WHEEL_NAMES
from cosim.core.symbolic_record import SymbolicRecord, symbolic_twin
from cosim.core.vehicle_params import VehicleParams
from estimation.bicycle import (
    BicycleParams,
    axle_forces,
    axle_lateral_velocity,
    cog_lateral_accel,
    world_velocity,
)
from estimation.state import STATE_NAMES, named_states
from estimation.wheel_slip import WheelLoads, slip_ratio, wheel_load

Params = ParamSpec("Params")


@dataclass(frozen=True)
class MeasurementModel:
    """A sensor's measurement equation ``z = h(x) + v`` over named channels.

    ``channels`` are the modelled channel names; ``ignored_channels`` may appear in the
    sensor's measurements but are dropped (e.g. the steered front wheel speeds);
    ``model_sigma`` is the standard deviation of the model's own error per channel, added
    to the measurement's covariance; ``angle_channels`` have their innovations wrapped.
    ``function`` returns ``h(x)`` and ``dh/dx``; ``value_function`` ``h(x)`` alone.
    """

    sensor: str
    channels: tuple[str, ...]
    model_sigma: tuple[float, ...]
    function: DenseFunction
    value_function: DenseFunction
    ignored_channels: tuple[str, ...] = ()
    angle_channels: tuple[str, ...] = ()
    def evaluate(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``h(x)`` (one value per channel) and its Jacobian ``dh/dx``."""
        h, jac = self.function(x)
        return h.reshape(-1), jac

    def value(self, x: np.ndarray) -> np.ndarray:
        """``h(x)``, one value per channel."""
        return self.value_function.vector(np.reshape(x, -1))

    @functools.cached_property
    def linear(self) -> bool:
        """Whether ``h`` is linear in the state (its Jacobian does not depend on it, as
        CasADi's graph of the model says): a sensor that measures states themselves."""
        function = self.function.function
        x = ca.SX.sym("x", function.size1_in(0))
        rest = [ca.SX.sym(f"p{i}", function.sparsity_in(i)) for i in range(1, function.n_in())]
        _, jacobian = function(x, *rest)
        return not ca.depends_on(jacobian, x)

    def select(self, names: tuple[str, ...]) -> tuple[tuple[int, ...], tuple[int, ...]]:
        """Rows of the model and columns of the measurement for the channels in ``names``.

        Raises ``ValueError`` on a channel the model neither models nor ignores.
        """
        model_rows: list[int] = []
        measurement_columns: list[int] = []
        for column, name in enumerate(names):
            if name in self.channels:
                model_rows.append(self.channels.index(name))
                measurement_columns.append(column)
            elif name not in self.ignored_channels:
                raise ValueError(
                    f"{self.sensor} measurement has channel {name!r}: expected some of "
                    f"{', '.join(self.channels + self.ignored_channels)}"
                )
        if len(set(model_rows)) != len(model_rows):
            raise ValueError(f"{self.sensor} measurement repeats a channel: {names}")
        return tuple(model_rows), tuple(measurement_columns)


@dataclass(frozen=True)
class WheelGeometry:
    """Where the wheels are and how large, as the measurement models believe it (SI)."""

    cog_front_m: float
    cog_rear_m: float
    track_front_m: float
    track_rear_m: float
    wheel_radius_m: float

    @classmethod
    def from_vehicle(cls, belief: VehicleParams) -> WheelGeometry:
        """The geometry of ``belief``, each axle's own track (``axle_tracks_m``)."""
        track_front, track_rear = belief.axle_tracks_m
        return cls(belief.cog_front_m, belief.cog_rear_m, float(track_front),
                   float(track_rear), belief.wheel_radius_m)

    @property
    def wheelbase_m(self) -> float:
        """``l_f + l_r``."""
        return self.cog_front_m + self.cog_rear_m


@dataclass(frozen=True)
class _Belief:
    """Every number of the measurement models, as one record (their ``belief`` input)."""

    bicycle: BicycleParams
    geometry: WheelGeometry
    loads: WheelLoads


def _measurement_functions(
    sensor: str, outputs: list[Callable[[dict[str, ca.SX]], ca.SX]],
    belief: SymbolicRecord[_Belief],
) -> tuple[DenseFunction, DenseFunction]:
    x = ca.SX.sym("x", len(STATE_NAMES))
    s = named_states(x)
    h = ca.densify(ca.vertcat(*[expr(s) for expr in outputs]))
    inputs = [x, belief.vector]
    return (
        DenseFunction(ca.Function(f"h_{sensor}", inputs, [h, ca.densify(ca.jacobian(h, x))]),
                      parameters=belief.values),
        # Shared where it is built: the UKF's library calls it through a map, which its
        # generation leaves as it is (cosim.core.compiled_function.subexpressions_shared).
        DenseFunction(ca.Function(f"h_{sensor}_value", inputs, [h], {"cse": True}),
                      parameters=belief.values),
    )


def _model(
    sensor: str,
    channels: tuple[str, ...],
    outputs: list[Callable[[dict[str, ca.SX]], ca.SX]],
    belief: SymbolicRecord[_Belief],
    model_sigma: tuple[float, ...] | None = None,
    **options: tuple[str, ...],
) -> MeasurementModel:
    function, value_function = _measurement_functions(sensor, outputs, belief)
    return MeasurementModel(
        sensor=sensor,
        channels=channels,
        model_sigma=model_sigma if model_sigma is not None else (0.0,) * len(channels),
        function=function,
        value_function=value_function,
        **options,
    )


def ackermann_angles(steer_rad: ca.SX, wheelbase_m: float, track_m: float) -> tuple[ca.SX, ca.SX]:
    """Left and right road-wheel angles for the bicycle angle ``steer_rad`` (Ackermann
    geometry, Gillespie, "Fundamentals of Vehicle Dynamics", ch. 6, as the plant steers:
    ``tan(delta_left) = L tan(delta) / (L - t/2 tan(delta))``, right with ``+``). The
    steering sensor's mean of the two differs from ``delta`` by O(delta^3)."""
    tan_delta = ca.tan(steer_rad)
    lever = 0.5 * track_m * tan_delta
    return (
        ca.atan2(wheelbase_m * tan_delta, wheelbase_m - lever),
        ca.atan2(wheelbase_m * tan_delta, wheelbase_m + lever),
    )


def wheel_spin(
    s: Mapping[str, ca.SX],
    wheel: str,
    belief: WheelGeometry,
    bicycle: BicycleParams,
    loads: WheelLoads | None = None,
    saturating: bool = False,
) -> ca.SX:
    """Spin rate of ``wheel`` (one of ``WHEEL_NAMES``) [rad/s]: rolling without longitudinal
    slip, or with the slip the brakes and the drive cause (``loads``,
    :mod:`estimation.wheel_slip`; ``saturating``: growing towards the tyre's peak, (S1')).

    The wheel centre moves with the rigid body, ``(vx - r y_w, vy_a + r x_w)`` in the
    vehicle frame at the wheel's position ``(x_w, y_w)`` (``vy_a``: the roll axis's lateral
    velocity, (R1)) (``x_w = l_f`` or ``-l_r``, ``y_w = +-t/2`` with ``t`` the believed
    track of that axle times ``wheel_track_scale``, left positive); the wheel spins at the
    component along its own plane (steered by its Ackermann angle at the front), over the
    believed radius times ``rolling_radius_scale``, times ``1 + kappa`` with the wheel's
    slip ratio ``kappa`` (:func:`estimation.wheel_slip.slip_ratio`) where ``loads`` is given;
    the radius then shortened by the tyre's deflection under the wheel's load ``F_z``
    (:func:`estimation.wheel_slip.wheel_load`), ``F_z / k_z`` with
    ``loads.vertical_compliance_mpn`` as ``1 / k_z``.
    """
    front = wheel.startswith("front")
    left = wheel.endswith("left")
    x_w = belief.cog_front_m if front else -belief.cog_rear_m
    track_front, track_rear = belief.track_front_m, belief.track_rear_m
    track = track_front if front else track_rear
    y_w = (0.5 if left else -0.5) * track * s["wheel_track_scale"]
    r = s["yaw_rate_radps"]
    forward = s["vx_mps"] - r * y_w
    sideways = axle_lateral_velocity(s, bicycle) + r * x_w
    if front:
        left_angle, right_angle = ackermann_angles(s["steer_rad"], belief.wheelbase_m, track_front)
        angle = left_angle if left else right_angle
        along = forward * ca.cos(angle) + sideways * ca.sin(angle)
        across = sideways * ca.cos(angle) - forward * ca.sin(angle)
    else:
        along, across = forward, sideways
    radius = belief.wheel_radius_m * s["rolling_radius_scale"]
    if loads is not None:
        load_n = wheel_load(s, front, left, track * s["wheel_track_scale"], loads)
        force_front, _, _ = axle_forces(s, bicycle)
        drag_n = force_front * ca.sin(s["steer_rad"])  # (S2): the steered tyres' pull
        # (S1)'s slip angle, guarded below 1 m/s (a wheel at rest has none to speak of)
        slip_angle = ca.atan(across / ca.fmax(ca.fabs(along), 1.0))
        along = along * (1.0 + slip_ratio(s, front, load_n, loads, drag_n, slip_angle,
                                          saturating))
        # The tyre's loaded radius (0 compliance: the same numbers).
        radius = radius - loads.vertical_compliance_mpn * load_n
    return along / radius


def free_rolling_wheels(belief: VehicleParams) -> tuple[str, ...]:
    """The wheels (of ``WHEEL_NAMES``) without drive torque, whose spin tells the speed over
    ground: the front wheels of a rear-wheel drive, the rear ones of a front-wheel drive,
    all four of an all-wheel drive (whose drive slip is left to the model sigma and the
    gate). A driven wheel slips by several per cent under acceleration and its inner wheel
    spins up in a hard turn (open differential), which no rolling-radius state follows."""
    if belief.drive == "rwd":
        return tuple(w for w in WHEEL_NAMES if w.startswith("front"))
    if belief.drive == "fwd":
        return tuple(w for w in WHEEL_NAMES if w.startswith("rear"))
    return WHEEL_NAMES


def _models_of_their_own(
        build: Callable[Params, dict[str, MeasurementModel]],
) -> Callable[Params, dict[str, MeasurementModel]]:
    """``build`` run once per process for equal arguments (its CasADi functions are
    immutable and shared), each call returning models with evaluators of their own."""
    cached = built_once(build)

    @functools.wraps(build)
    def models(*args: Params.args, **kwargs: Params.kwargs) -> dict[str, MeasurementModel]:
        return {sensor: dataclasses.replace(model, function=model.function.fresh(),
                                            value_function=model.value_function.fresh())
                for sensor, model in cached(*args, **kwargs).items()}

    return models


@_models_of_their_own
def build_measurement_models(
    belief: VehicleParams,
    wheel_model_sigma_mps: float,
    lateral_accel_model_sigma_mps2: float,
    steer_model_sigma_rad: float = 0.0,
    bicycle: BicycleParams | None = None,
    wheel_slip_per_force_ratio: float = 0.0,
    wheel_slip_combined_stiffness_1prad: float = 0.0,
    wheel_slip_saturation: tuple[float, float, float] | None = None,
    tyre_vertical_compliance_mpn: float = 0.0,
) -> dict[str, MeasurementModel]:
    """The measurement models of every sensor the filters fuse, by sensor name.

    - ``gnss``: CoG position in the world frame.
    - ``gnss_velocity`` (optional, a receiver's Doppler velocity): the CoG's velocity in the
      world frame, ``R(yaw) (vx, vy)``; it observes the course ``yaw + vy / vx`` directly, not
      only through the track of positions.
    - ``imu``: yaw rate plus the gyro bias; the kinematic accelerations of the CoG in the
      vehicle frame: ``ax`` a state plus the accelerometer's bias, ``ay = vy' + r vx``
      (:func:`cog_lateral_accel`, (D4)) plus the lateral accelerometer's bias.
    - ``wheel_speed``: spin of the freely rolling wheels (:func:`free_rolling_wheels`,
      :func:`wheel_spin`); the driven wheels' channels are ignored. The difference between
      the left and the right wheel is ``r t / R`` (yaw rate, track, radius): with the gyro
      measuring ``r``, it would tell the filter the rolling-radius scale through the track
      ``t``, which the belief does not know well (the contact patches move with load and
      camber; on the MuJoCo sedan the front wheels' effective track, steering included, is
      about 6 % wider than the bicycle's). Believed exactly, a few per cent of track error
      became a per-cent error of the rolling radius and so of the speed, 0.3 m/s in the
      lane change with the 0.5 m GNSS. So the effective track is a state too,
      ``wheel_track_scale`` (the track over the believed one): the left-right difference
      in turns estimates it, the common mode the rolling radius.
      With ``wheel_slip_per_force_ratio`` above 0 each wheel's spin has the longitudinal
      slip the brakes (and an all-wheel drive's drive) cause (:mod:`estimation.wheel_slip`),
      growing towards the tyre's peak by ``wheel_slip_saturation`` (``(mu, C, E)`` of (S1');
      None: in proportion to the force).
    - ``steering``: the front road-wheel angle ``steer_rad``.
    - ``heading`` (optional, e.g. a dual-antenna GNSS): ``yaw_rad`` directly.

    ``bicycle`` is the dynamic bicycle the filter believes (None: ``belief``'s with the
    default tyre law, no roll, load transfer or relaxation;
    :func:`estimation.belief_models.bicycle_params` builds a filter's from its configuration).
    Every number of the belief (the bicycle's, the wheels' geometry) is an input of the
    models' functions, set once, not a constant: one function, and one compiled library,
    serves every belief (each ``h`` with its Jacobian, :attr:`MeasurementModel.function`,
    is what the EKF compiles). The functions are built once per process for equal arguments;
    each call returns models with evaluators of their own.
    """
    believed = BicycleParams.from_vehicle(belief) if bicycle is None else bicycle
    numbers = symbolic_twin(_Belief(believed, WheelGeometry.from_vehicle(belief),
                                    WheelLoads.from_vehicle(belief, wheel_slip_per_force_ratio,
                                                            wheel_slip_combined_stiffness_1prad,
                                                            wheel_slip_saturation,
                                                            tyre_vertical_compliance_mpn)))
    bicycle, geometry = numbers.twin.bicycle, numbers.twin.geometry
    loads = numbers.twin.loads if wheel_slip_per_force_ratio > 0.0 else None
    common = {"belief": numbers}
    wheel_sigma_radps = wheel_model_sigma_mps / belief.wheel_radius_m
    fused = free_rolling_wheels(belief)
    ignored = tuple(f"{w}_radps" for w in WHEEL_NAMES if w not in fused)
    models = [
        _model("gnss", ("x_m", "y_m"), [lambda s: s["x_m"], lambda s: s["y_m"]], **common),
        _model(
            "gnss_velocity",
            ("v_east_mps", "v_north_mps"),
            [lambda s: world_velocity(s)[0], lambda s: world_velocity(s)[1]],
            **common,
        ),
        _model(
            "imu",
            ("yaw_rate_radps", "ax_mps2", "ay_mps2"),
            [
                lambda s: s["yaw_rate_radps"] + s["gyro_bias_radps"],
                lambda s: s["ax_mps2"] + s["ax_bias_mps2"],
                lambda s: cog_lateral_accel(s, bicycle) + s["ay_bias_mps2"],
            ],
            **common,
            model_sigma=(0.0, 0.0, lateral_accel_model_sigma_mps2),
        ),
        _model(
            "wheel_speed",
            tuple(f"{w}_radps" for w in fused),
            [lambda s, w=w: wheel_spin(s, w, geometry, bicycle, loads,
                                       wheel_slip_saturation is not None) for w in fused],
            **common,
            model_sigma=(wheel_sigma_radps,) * len(fused),
            ignored_channels=ignored,
        ),
        _model(
            "steering",
            ("steer_rad",),
            [lambda s: s["steer_rad"]],
            **common,
            model_sigma=(steer_model_sigma_rad,),
        ),
        _model("heading", ("yaw_rad",), [lambda s: s["yaw_rad"]], **common,
               angle_channels=("yaw_rad",)),
    ]
    return {model.sensor: model for model in models}
