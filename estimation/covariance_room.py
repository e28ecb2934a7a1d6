"""Room made in a filter's covariance for what its model did not predict, and a cold start.

Three operations on a belief ``(x, P)``, each returning the new one; the filter
(:class:`estimation.fusion.KalmanFusion`) decides when:

- :func:`room_for_jump`: a sensor that has disagreed for ``gate_release_s`` is believed;
- :func:`room_for_surprise`: an ungated sensor (the IMU) far outside its gate;
- :func:`first_fix`: the first GNSS fix of a run started without one.
"""

from __future__ import annotations

import numpy as np


def room_for_jump(p: np.ndarray, jacobian: np.ndarray, innovation: np.ndarray) -> np.ndarray:
    """The covariance with room for a persistent jump, before a gate-released update.

    The state is taken to have jumped. The covariance grows by ``G y y' G'`` with
    ``G = D H' (H D H')^-1`` and ``D = diag(P)``: the jump ``y`` is explained by the states
    the channels observe, shared in proportion to their variances (a GNSS jump moves the
    position only, not the speed through its correlation with the position). Afterwards the
    innovation has NIS ``n / (1 + n)`` < 1 and the update fuses it as an ordinary
    measurement. ``np.linalg.LinAlgError`` when ``H D H'`` is singular.
    """
    spread = np.diag(p)[:, None] * jacobian.T
    gain = spread @ np.linalg.inv(jacobian @ spread)
    jump = gain @ np.asarray(innovation, dtype=float).reshape(-1)
    return p + np.outer(jump, jump)


def room_for_surprise(p: np.ndarray, process_noise: np.ndarray, jacobian: np.ndarray,
                      innovation: np.ndarray, nis: float,
                      threshold: float) -> np.ndarray | None:
    """The covariance with room for a manoeuvre an ungated sensor saw and the model did not
    predict (None: ``H Q H'`` singular, no room made).

    The IMU is never gated: it is the filter's one direct view of sudden motion (a yaw
    kick, a kerb strike). When its NIS ``n`` is above the gate ``threshold``, the innovation
    is taken as a jump of the states the process noise drives, the adjustable process noise
    of Bar-Shalom, Li, Kirubarajan, "Estimation with Applications to Tracking and
    Navigation" (Wiley 2001), section 11.2: the covariance grows by ``a G y y' G'`` with
    ``G = Q H' (H Q H')^-1`` and ``Q`` the process noise of one sub-step at the current
    mean, so a gyro's surprise moves the yaw rate (driven by the yaw-acceleration noise) and
    not the gyro bias (driven by a slow random walk).

    The room is the least that makes the innovation pass the gate: since ``H G = I`` the
    innovation's covariance becomes ``S + a y y'``, whose NIS is ``n / (1 + a n)``
    (Sherman-Morrison), equal to the threshold for ``a = 1 / threshold - 1 / n``. A kick's
    innovation (``n`` in the thousands) gets ``a`` near ``1 / threshold`` and is still
    followed almost at once (the update moves ``H x`` by ``a y y' S'^-1 y = a threshold y``);
    the sensor's own noise far in its tail (``n`` just above the gate, some 1 update in
    10^4 for the IMU at the default gate) gets little room, instead of the whole innovation
    taken as motion (``a = 1``), which let one 4-sigma accelerometer sample move the
    steering by several of its sigmas.
    """
    room = 1.0 / threshold - 1.0 / nis
    if not room > 0.0:
        return None
    spread = process_noise @ jacobian.T
    try:
        gain = spread @ np.linalg.inv(jacobian @ spread)
    except np.linalg.LinAlgError:
        return None
    jump = gain @ np.asarray(innovation, dtype=float).reshape(-1)
    return p + room * np.outer(jump, jump)


def first_fix(x: np.ndarray, p: np.ndarray, rows: list[int], z: np.ndarray,
              r_matrix: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``first-fix``: the states ``rows`` (the position) become the fix ``z``, their
    covariance the believed GNSS noise ``r_matrix``, uncorrelated with the other states (a
    receiver's cold start)."""
    mean = np.array(x, dtype=float)
    mean[rows] = z
    covariance = np.array(p, dtype=float)
    covariance[rows, :] = 0.0
    covariance[:, rows] = 0.0
    covariance[np.ix_(rows, rows)] = r_matrix
    return mean, covariance
