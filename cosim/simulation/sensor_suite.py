"""The run's sensors: each with its period in physics steps, its random stream and its faults.

A sensor's period is a whole number of physics steps (checked when the run is built); its
random generator is the run seed's stream named ``sensors.<name>``
(:func:`cosim.simulation.seeding.component_rng`), so adding a sensor changes no other
sensor's noise; its faults (:mod:`cosim.sensing.faults`) are applied to each sample, in
time order, a dropout delivering nothing. A sensor with a latency (``sensors.gnss.latency_s``,
a whole number of physics steps) delivers each sample that many steps after it was taken,
with the time it was taken, before the samples taken at the delivery step. A filter that
asks for the truth (``required_sensors`` holding ``truth``) gets a noise-free
:class:`TruthSensor` at the faster of the log and control rates.
"""

from __future__ import annotations

from collections import deque

from cosim.core.records import Measurement, VehicleState
from cosim.core.sensor_names import GNSS, GNSS_VELOCITY, TRUTH
from cosim.sensing.faults import FaultInjector
from cosim.sensing.protocol import BiasedSensor, Sensor
from cosim.sensing.sensors import TruthSensor, make_sensors
from cosim.simulation.scenario_config import ScenarioConfig, steps_per_period
from cosim.simulation.seeding import component_rng


class SensorSuite:
    """The sensors of one run (module docstring)."""

    def __init__(self, config: ScenarioConfig, required_sensors: tuple[str, ...],
                 dt_s: float) -> None:
        sensors: list[Sensor] = make_sensors(config.sensors)
        if TRUTH in required_sensors:
            sensors.append(TruthSensor(min(config.sim.log_period_s,
                                           config.sim.control_period_s)))
        self.sensors = sensors
        self.steps = [steps_per_period(s.period_s, dt_s, f"sensors.{s.name}.period_s")
                      for s in sensors]
        """Each sensor's period, in physics steps."""
        self._rngs = [component_rng(config.seed, f"sensors.{s.name}") for s in sensors]
        self._faults = [FaultInjector(config.faults, s.name, s.names) for s in sensors]
        self._biased = [s for s in sensors if isinstance(s, BiasedSensor)]
        receiver_latency_s = config.sensors.gnss.latency_s  # its fix and its velocity
        latency_s = {GNSS: receiver_latency_s, GNSS_VELOCITY: receiver_latency_s}
        self.latency_steps = [
            steps_per_period(latency_s.get(s.name, 0.0), dt_s, "sensors.gnss.latency_s")
            for s in sensors]
        """Each sensor's latency, in physics steps."""
        self._held: deque[tuple[int, Measurement]] = deque()
        """Samples taken and not yet delivered, with the step they are due at, in order."""

    @property
    def names(self) -> list[str]:
        return [s.name for s in self.sensors]

    def sample(self, k: int, truth: VehicleState) -> list[Measurement]:
        """What the sensors deliver at physics step ``k`` (faults applied; a dropout
        delivers nothing): the late samples now due, then those taken now, in the sensors'
        order."""
        held = self._held
        delivered = []
        while held and held[0][0] <= k:
            delivered.append(held.popleft()[1])
        for sensor, steps, rng, faults, latency in zip(
                self.sensors, self.steps, self._rngs, self._faults, self.latency_steps,
                strict=True):
            if k % steps:
                continue
            measurement = faults.apply(sensor.sample(truth, rng))
            if measurement is None:
                continue
            if latency:
                held.append((k + latency, measurement))
            else:
                delivered.append(measurement)
        return delivered

    def true_biases(self) -> dict[str, float]:
        """The true biases of the sensors that have them (for the truth's log message)."""
        biases: dict[str, float] = {}
        for sensor in self._biased:
            biases.update(sensor.true_biases())
        return biases

    def faults_injected(self) -> int:
        """How many faults the run's sensors have had so far."""
        return sum(f.injected for f in self._faults)
