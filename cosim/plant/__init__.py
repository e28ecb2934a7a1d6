"""The truth: the MuJoCo car, its tyres and actuation, traffic and disturbances.

MuJoCo is imported here, first, without OpenGL (:mod:`cosim.plant.headless`): a bad
``MUJOCO_GL`` must not stop a run that renders nothing.
"""

from cosim.plant.headless import import_mujoco

import_mujoco()
