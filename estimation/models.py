"""Process and measurement models of the EKF, built symbolically with CasADi.

State (world frame ENU for the pose, vehicle frame ISO 8855 for the rates), named by
:data:`STATE_NAMES`:

========================  ==================================================================
``x_m``, ``y_m``          position of the centre of gravity (CoG), world frame
``yaw_rad``               heading of the vehicle x axis, CCW from world x, wrapped (-pi, pi]
``vx_mps``, ``vy_mps``    velocity of the CoG in the vehicle frame
``yaw_rate_radps``        yaw rate r
``ax_mps2``               kinematic acceleration of the CoG along the vehicle x axis (what
                          a gravity-compensated IMU measures; ``d vx/dt = ax + r vy``)
``rolling_radius_scale``  effective rolling radius of the rear wheels over the believed one
                          (tyre deflection, wear, steady drive slip); dimensionless, ~1
========================  ==================================================================

Process model: constant turn rate and acceleration (CTRA, Schubert et al., "Comparison and
evaluation of advanced motion models for vehicle tracking", FUSION 2008) extended with a
lateral velocity (the sideslip of a real car, which makes the course over ground differ from
the heading). In continuous time::

    dx/dt  = vx cos(yaw) - vy sin(yaw)          d vx/dt = ax + r vy
    dy/dt  = vx sin(yaw) + vy cos(yaw)          d vy/dt = -vy / tau + w_vy
    dyaw/dt = r + w_yaw                         dr/dt   = w_r
    (dx, dy)/dt += w_pos                        d ax/dt = w_j
                                                d k/dt  = w_k    (k: rolling_radius_scale)

with independent white noises ``w`` of the configured power spectral densities. ``vy`` is a
first-order Gauss-Markov process: without lateral-force information (no steering angle, no
tyre model) the filter knows only that the sideslip is small and does not persist; the
difference between the course seen by GNSS and the heading integrated from the gyro is what
drives it. With ``vy = 0`` the model is the textbook CTRA.

Discretisation over a sub-step ``dt``: the mean by one classical Runge-Kutta 4 step (no
singularity at zero yaw rate, unlike the closed-form CTRA), its Jacobian ``F`` by CasADi's
automatic differentiation of that step, and the process noise by the exact integral of the
linearised system (Van Loan 1978; ``dQ/dt = A Q + Q A' + W``, ``Q(0) = 0``) written as its
power series ``Q(dt) = sum_k dt^(k+1)/(k+1)! L^k(W)`` with ``L(X) = A X + X A'``. The
coupling graph of ``A`` is acyclic apart from the ``-1/tau`` self-loop of ``vy``, so the
series converges like ``(dt/tau)^k / k!``; :data:`NOISE_SERIES_TERMS` terms are exact to
rounding for ``dt <= 0.02 s`` and ``tau >= 0.1 s``, which is why those are the limits.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import casadi as ca
import numpy as np

from cosim.records import WHEEL_NAMES
from cosim.vehicle_params import VehicleParams

VEHICLE_STATE_NAMES: tuple[str, ...] = (
    "x_m",
    "y_m",
    "yaw_rad",
    "vx_mps",
    "vy_mps",
    "yaw_rate_radps",
    "ax_mps2",
)
"""The EKF's states that describe the car's motion (named as in VehicleState)."""

SENSOR_STATE_NAMES: tuple[str, ...] = ("rolling_radius_scale",)
"""The EKF's states that describe its sensors: effective rolling radius / believed radius."""

STATE_NAMES: tuple[str, ...] = VEHICLE_STATE_NAMES + SENSOR_STATE_NAMES
"""Names of the EKF's states, in the order of its mean and covariance."""

ANGLE_STATES: tuple[str, ...] = ("yaw_rad",)
"""States that are angles: wrapped to (-pi, pi] after every step."""

NOISE_SERIES_TERMS = 10
"""Terms of the power series of the discrete process noise (see the module docstring)."""

MIN_LATERAL_TIME_CONSTANT_S = 0.1
"""Smallest ``tau`` of the vy Gauss-Markov process the noise series is exact for."""

MAX_STEP_S = 0.02
"""Longest sub-step the noise series is exact for."""


def wrap_angle(angle_rad: float | np.ndarray) -> float | np.ndarray:
    """Wrap an angle (or an array of angles) to (-pi, pi]."""
    if np.ndim(angle_rad) == 0 and -math.pi < float(angle_rad) <= math.pi:
        return float(angle_rad)  # the common case, without array overhead
    angle = np.asarray(angle_rad, dtype=float)
    wrapped = np.pi - np.mod(np.pi - angle, 2.0 * np.pi)
    # np.mod(-tiny, 2 pi) rounds to 2 pi, which would give -pi: move it to +pi.
    wrapped = np.where(wrapped <= -np.pi, wrapped + 2.0 * np.pi, wrapped)
    # Angles already in range are returned untouched (no rounding).
    wrapped = np.where((angle > -np.pi) & (angle <= np.pi), angle, wrapped)
    return float(wrapped) if np.ndim(wrapped) == 0 else wrapped


class DenseFunction:
    """Fast evaluation of a CasADi Function with dense numeric inputs and outputs.

    Calls go through CasADi's buffer interface into arrays allocated once (about 1 us
    instead of about 25 us for a call with DM conversions); results are returned as copies.
    Every output of ``function`` must be dense (build it with ``ca.densify``).
    """

    def __init__(self, function: ca.Function) -> None:
        self.function = function
        for i in range(function.n_out()):
            if not function.sparsity_out(i).is_dense():
                raise ValueError(f"{function.name()}: output {i} must be dense")
        # CasADi stores matrices column-major and its buffers must be C-contiguous numpy
        # arrays, so each matrix lives in an array of the transposed shape.
        self._inputs = [np.zeros(function.size_in(i)[::-1]) for i in range(function.n_in())]
        self._outputs = [np.zeros(function.size_out(i)[::-1]) for i in range(function.n_out())]
        self._buffer, self._evaluate = function.buffer()
        for i, array in enumerate(self._inputs):
            self._buffer.set_arg(i, memoryview(array))
        for i, array in enumerate(self._outputs):
            self._buffer.set_res(i, memoryview(array))

    def __call__(self, *args: np.ndarray | float) -> tuple[np.ndarray, ...]:
        """The outputs (each of the shape CasADi declares) for the inputs ``args``."""
        if len(args) != len(self._inputs):
            raise TypeError(f"{self.function.name()} takes {len(self._inputs)} inputs")
        for array, value in zip(self._inputs, args, strict=True):
            array.T[...] = np.reshape(value, array.T.shape)
        self._evaluate()
        return tuple(array.T.copy() for array in self._outputs)


def state_index(name: str) -> int:
    """Position of the state ``name`` in :data:`STATE_NAMES` (a clear error if unknown)."""
    if name not in STATE_NAMES:
        raise KeyError(f"unknown state {name!r}: expected one of {', '.join(STATE_NAMES)}")
    return STATE_NAMES.index(name)


def _named(vector: ca.SX) -> dict[str, ca.SX]:
    """The entries of a symbolic state vector by name."""
    return {name: vector[i] for i, name in enumerate(STATE_NAMES)}


def _stack(values: Mapping[str, ca.SX | float]) -> ca.SX:
    """A symbolic state vector from one expression per state name."""
    missing = set(STATE_NAMES) - set(values)
    if missing:
        raise KeyError(f"missing state(s) {sorted(missing)}")
    return ca.vertcat(*[values[name] for name in STATE_NAMES])


@dataclass(frozen=True)
class ProcessNoise:
    """Continuous-time white-noise power spectral densities driving the states."""

    position_psd_m2ps: float
    yaw_psd_rad2ps: float
    lateral_accel_psd_m2ps3: float
    yaw_accel_psd_rad2ps3: float
    jerk_psd_m2ps5: float
    rolling_radius_scale_psd_1ps: float

    def __post_init__(self) -> None:
        for name, value in vars(self).items():
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name} = {value!r}: expected a finite number >= 0")

    def diagonal(self) -> np.ndarray:
        """The PSD matrix W (diagonal), one entry per state of :data:`STATE_NAMES`."""
        psd = {
            "x_m": self.position_psd_m2ps,
            "y_m": self.position_psd_m2ps,
            "yaw_rad": self.yaw_psd_rad2ps,
            "vx_mps": 0.0,
            "vy_mps": self.lateral_accel_psd_m2ps3,
            "yaw_rate_radps": self.yaw_accel_psd_rad2ps3,
            "ax_mps2": self.jerk_psd_m2ps5,
            "rolling_radius_scale": self.rolling_radius_scale_psd_1ps,
        }
        return np.diag([psd[name] for name in STATE_NAMES])


class ProcessModel:
    """The CTRA process model with its CasADi-built discretisation.

    The CasADi functions are built once, here; :meth:`step` only evaluates them.
    """

    def __init__(self, noise: ProcessNoise, lateral_time_constant_s: float) -> None:
        if not (
            math.isfinite(lateral_time_constant_s)
            and lateral_time_constant_s >= MIN_LATERAL_TIME_CONSTANT_S
        ):
            raise ValueError(
                f"lateral_time_constant_s = {lateral_time_constant_s!r}: expected a number "
                f">= {MIN_LATERAL_TIME_CONSTANT_S}"
            )
        self.noise = noise
        self.lateral_time_constant_s = lateral_time_constant_s
        n = len(STATE_NAMES)
        x = ca.SX.sym("x", n)
        dt = ca.SX.sym("dt_s")

        k1 = self._derivative(x)
        k2 = self._derivative(x + 0.5 * dt * k1)
        k3 = self._derivative(x + 0.5 * dt * k2)
        k4 = self._derivative(x + dt * k3)
        x_next = x + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        transition = ca.jacobian(x_next, x)

        a = ca.jacobian(self._derivative(x), x)
        term = ca.SX(ca.DM(noise.diagonal()))
        q = ca.SX.zeros(n, n)
        factor = dt
        for k in range(NOISE_SERIES_TERMS):
            q = q + factor * term
            term = a @ term + term @ a.T
            factor = factor * dt / (k + 2)
        q = 0.5 * (q + q.T)

        self.derivative_function = ca.Function(
            "ctra_derivative", [x], [self._derivative(x), ca.densify(a)]
        )
        self.step_function = ca.Function(
            "ctra_step", [x, dt], [x_next, ca.densify(transition), ca.densify(q)]
        )
        self._derivative_fast = DenseFunction(self.derivative_function)
        self._step_fast = DenseFunction(self.step_function)

    def _derivative(self, x: ca.SX) -> ca.SX:
        s = _named(x)
        cos_yaw, sin_yaw = ca.cos(s["yaw_rad"]), ca.sin(s["yaw_rad"])
        r = s["yaw_rate_radps"]
        return _stack(
            {
                "x_m": s["vx_mps"] * cos_yaw - s["vy_mps"] * sin_yaw,
                "y_m": s["vx_mps"] * sin_yaw + s["vy_mps"] * cos_yaw,
                "yaw_rad": r,
                "vx_mps": s["ax_mps2"] + r * s["vy_mps"],
                "vy_mps": -s["vy_mps"] / self.lateral_time_constant_s,
                "yaw_rate_radps": 0.0,
                "ax_mps2": 0.0,
                "rolling_radius_scale": 0.0,
            }
        )

    def derivative(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The noise-free time derivative of the state and its Jacobian ``A`` at ``x``."""
        f, a = self._derivative_fast(np.asarray(x, dtype=float).reshape(-1))
        return f.reshape(-1), a

    def step(self, x: np.ndarray, dt_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One sub-step: the predicted mean (column), its Jacobian F and the noise Q.

        ``dt_s`` must not exceed :data:`MAX_STEP_S` (the filter splits longer intervals).
        """
        if not 0.0 <= dt_s <= MAX_STEP_S * (1.0 + 1e-9):
            raise ValueError(f"dt_s = {dt_s!r}: expected a sub-step in [0, {MAX_STEP_S}] s")
        return self._step_fast(x, dt_s)


@dataclass(frozen=True)
class MeasurementModel:
    """A sensor's measurement equation ``z = h(x) + v`` over named channels.

    ``channels`` are the modelled channel names; ``ignored_channels`` may appear in the
    sensor's measurements but are dropped (e.g. the steered front wheel speeds);
    ``model_sigma`` is the standard deviation of the model's own error per channel, added
    to the measurement's covariance; ``angle_channels`` have their innovations wrapped.
    """

    sensor: str
    channels: tuple[str, ...]
    model_sigma: tuple[float, ...]
    function: DenseFunction
    ignored_channels: tuple[str, ...] = ()
    angle_channels: tuple[str, ...] = ()

    def evaluate(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``h(x)`` (one value per channel) and its Jacobian ``dh/dx``."""
        h, jac = self.function(x)
        return h.reshape(-1), jac

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


def _measurement_function(
    sensor: str, outputs: list[Callable[[dict[str, ca.SX]], ca.SX]]
) -> DenseFunction:
    x = ca.SX.sym("x", len(STATE_NAMES))
    s = _named(x)
    h = ca.vertcat(*[expr(s) for expr in outputs])
    return DenseFunction(
        ca.Function(f"h_{sensor}", [x], [ca.densify(h), ca.densify(ca.jacobian(h, x))])
    )


def build_measurement_models(
    belief: VehicleParams, wheel_model_sigma_mps: float, lateral_accel_model_sigma_mps2: float
) -> dict[str, MeasurementModel]:
    """The measurement models of every sensor the EKF fuses, by sensor name.

    - ``gnss``: CoG position in the world frame.
    - ``imu``: yaw rate; kinematic accelerations in the vehicle frame, ``ax`` a state and
      ``ay = r vx`` (kinematic, the ``dvy/dt`` term is left to ``model_sigma``).
    - ``wheel_speed``: spin of the (unsteered) rear wheels; the centre of the rear-left
      wheel moves forward at ``vx - r track/2`` (rigid body, left is +y), the rear-right at
      ``vx + r track/2``; spin = that speed / (believed radius * rolling_radius_scale).
      Front wheels are steered by an angle the filter does not know; their channels are
      ignored.
    - ``heading`` (optional, e.g. a dual-antenna GNSS): ``yaw_rad`` directly.
    """
    radius_m = belief.wheel_radius_m
    half_track_m = 0.5 * belief.track_m
    wheel_sigma_radps = wheel_model_sigma_mps / radius_m
    rear_left, rear_right = (f"{w}_radps" for w in WHEEL_NAMES if w.startswith("rear"))
    front = tuple(f"{w}_radps" for w in WHEEL_NAMES if w.startswith("front"))
    models = [
        MeasurementModel(
            sensor="gnss",
            channels=("x_m", "y_m"),
            model_sigma=(0.0, 0.0),
            function=_measurement_function("gnss", [lambda s: s["x_m"], lambda s: s["y_m"]]),
        ),
        MeasurementModel(
            sensor="imu",
            channels=("yaw_rate_radps", "ax_mps2", "ay_mps2"),
            model_sigma=(0.0, 0.0, lateral_accel_model_sigma_mps2),
            function=_measurement_function(
                "imu",
                [
                    lambda s: s["yaw_rate_radps"],
                    lambda s: s["ax_mps2"],
                    lambda s: s["yaw_rate_radps"] * s["vx_mps"],
                ],
            ),
        ),
        MeasurementModel(
            sensor="wheel_speed",
            channels=(rear_left, rear_right),
            model_sigma=(wheel_sigma_radps, wheel_sigma_radps),
            function=_measurement_function(
                "wheel_speed",
                [
                    lambda s: (
                        (s["vx_mps"] - half_track_m * s["yaw_rate_radps"])
                        / (radius_m * s["rolling_radius_scale"])
                    ),
                    lambda s: (
                        (s["vx_mps"] + half_track_m * s["yaw_rate_radps"])
                        / (radius_m * s["rolling_radius_scale"])
                    ),
                ],
            ),
            ignored_channels=front,
        ),
        MeasurementModel(
            sensor="heading",
            channels=("yaw_rad",),
            model_sigma=(0.0,),
            function=_measurement_function("heading", [lambda s: s["yaw_rad"]]),
            angle_channels=("yaw_rad",),
        ),
    ]
    return {model.sensor: model for model in models}
