"""The pure-pursuit tracker as an FMI 3.0 co-simulation FMU, built with pythonfmu3.

``python -m pythonfmu3 build -f pure_pursuit_fmi3.py pure_pursuit_law.py``
(examples/fmu/build.py does it). The law is in :mod:`pure_pursuit_law`; units are declared
(FMI 3 needs each one defined in ``UnitDefinitions``, with its SI base units).
"""

from pure_pursuit_law import PREVIEW_POINTS, outputs
from pythonfmu3 import Float64, Fmi3Causality, Fmi3Slave, Fmi3Variability
from pythonfmu3.unit import Unit

INPUTS = ("speed_mps", "ref_speed_mps")
PARAMETERS = {"wheelbase_m": (2.8, "m"), "cog_rear_m": (1.6, "m"),
              "understeer_radpmps2": (0.0039, "rad.s2/m"),
              "lookahead_time_s": (0.6, "s"),
              "lookahead_min_m": (4.0, "m"), "lookahead_max_m": (40.0, "m"),
              "speed_gain_1ps": (1.0, "1/s")}
UNITS = (Unit("m", m=1), Unit("s", s=1), Unit("1/s", s=-1), Unit("m/s", m=1, s=-1),
         Unit("m/s2", m=1, s=-2), Unit("rad", rad=1), Unit("rad.s2/m", rad=1, s=2, m=-1))


class PurePursuitFmi3(Fmi3Slave):
    """Pure pursuit on cosim's preview points, with a proportional speed loop."""

    description = "Pure pursuit (Coulter 1992) on cosim's preview points"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.register_units(list(UNITS))
        self.time = 0.0
        self.register_variable(Float64("time", causality=Fmi3Causality.independent,
                                       variability=Fmi3Variability.continuous))
        self.xs = [0.0] * PREVIEW_POINTS
        self.ys = [0.0] * PREVIEW_POINTS
        for name in INPUTS:
            setattr(self, name, 0.0)
            self.register_variable(Float64(name, causality=Fmi3Causality.input, start=0.0,
                                           unit="m/s"))
        for name, (value, unit) in PARAMETERS.items():
            setattr(self, name, value)
            self.register_variable(Float64(name, causality=Fmi3Causality.parameter,
                                           variability=Fmi3Variability.fixed, start=value,
                                           unit=unit))
        for i in range(PREVIEW_POINTS):
            for axis, values in (("x", self.xs), ("y", self.ys)):
                self.register_variable(Float64(
                    f"preview_{axis}_m[{i + 1}]", causality=Fmi3Causality.input, start=0.0,
                    unit="m", getter=lambda values=values, i=i: values[i],
                    setter=lambda value, values=values, i=i: values.__setitem__(i, value)))
        self.steer_rad = 0.0
        self.accel_mps2 = 0.0
        self.register_variable(Float64("steer_rad", causality=Fmi3Causality.output,
                                       unit="rad"))
        self.register_variable(Float64("accel_mps2", causality=Fmi3Causality.output,
                                       unit="m/s2"))

    def do_step(self, current_time, step_size):
        self.steer_rad, self.accel_mps2 = outputs(self)
        return True
