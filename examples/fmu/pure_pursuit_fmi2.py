"""The pure-pursuit tracker as an FMI 2.0 co-simulation FMU, built with pythonfmu.

``python -m pythonfmu build -f pure_pursuit_fmi2.py pure_pursuit_law.py``
(examples/fmu/build.py does it). The law is in :mod:`pure_pursuit_law`.
"""

from pure_pursuit_law import PREVIEW_POINTS, outputs
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real

INPUTS = ("speed_mps", "ref_speed_mps")
PARAMETERS = {"wheelbase_m": 2.8, "cog_rear_m": 1.6,
              "understeer_radpmps2": 0.0039, "lookahead_time_s": 0.6, "lookahead_min_m": 4.0,
              "lookahead_max_m": 40.0, "speed_gain_1ps": 1.0}


class PurePursuitFmi2(Fmi2Slave):
    """Pure pursuit on cosim's preview points, with a proportional speed loop."""

    description = "Pure pursuit (Coulter 1992) on cosim's preview points"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.xs = [0.0] * PREVIEW_POINTS
        self.ys = [0.0] * PREVIEW_POINTS
        for name in INPUTS:
            setattr(self, name, 0.0)
            self.register_variable(Real(name, causality=Fmi2Causality.input, start=0.0))
        for name, value in PARAMETERS.items():
            setattr(self, name, value)
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.fixed, start=value))
        for i in range(PREVIEW_POINTS):
            for axis, values in (("x", self.xs), ("y", self.ys)):
                self.register_variable(Real(
                    f"preview_{axis}_m[{i + 1}]", causality=Fmi2Causality.input, start=0.0,
                    getter=lambda values=values, i=i: values[i],
                    setter=lambda value, values=values, i=i: values.__setitem__(i, value)))
        self.steer_rad = 0.0
        self.accel_mps2 = 0.0
        self.register_variable(Real("steer_rad", causality=Fmi2Causality.output))
        self.register_variable(Real("accel_mps2", causality=Fmi2Causality.output))

    def do_step(self, current_time, step_size):
        self.steer_rad, self.accel_mps2 = outputs(self)
        return True
