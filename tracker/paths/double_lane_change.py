"""The double-lane-change path (Falcone et al. 2007).

Falcone, Borrelli, Asgari, Tseng, Hrovat, "Predictive active steering control for
autonomous vehicle systems", IEEE Trans. Control Systems Technology 15(3):566-580, 2007:

    z1 = a1 (x - b1) - c1,   z2 = a2 (x - b2) - c2
    y  = y1 (1 + tanh z1) - y2 (1 + tanh z2)

Falcone's constants need 1.11 g at 20 m/s; stretched along x by 1.5 the path needs 0.50 g,
the manoeuvre the ``dynamic-mpc`` design targets (9.5 deg of steering on its model).
``stretch`` scales the x-constants: a_i -> a_i / stretch, b_i -> b_i * stretch.
"""

from __future__ import annotations

import numpy as np

from tracker.paths.reference_path import ReferencePath

A1, B1, C1, Y1 = 2.4 / 25.0, 27.19, 1.2, 4.05 / 2.0
A2, B2, C2, Y2 = 2.4 / 21.95, 56.46, 1.2, 5.7 / 2.0


def lateral_offset_m(x_m: np.ndarray, stretch: float = 1.5) -> np.ndarray:
    """y_ref(x) of the double lane change, eq. 16, stretched along x by ``stretch``."""
    z1 = A1 / stretch * (x_m - B1 * stretch) - C1
    z2 = A2 / stretch * (x_m - B2 * stretch) - C2
    return Y1 * (1.0 + np.tanh(z1)) - Y2 * (1.0 + np.tanh(z2))


def double_lane_change(
    speed_mps: float, stretch: float = 1.5, length_m: float = 500.0, step_m: float = 0.5
) -> ReferencePath:
    """The double lane change from x = 0 to ``length_m`` at a constant reference speed."""
    x = np.arange(0.0, length_m + step_m, step_m)
    return ReferencePath(x, lateral_offset_m(x, stretch), speed_mps)
