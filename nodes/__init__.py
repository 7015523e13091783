"""cosim nodes: the pure step kinds (physics, sensors, control, the foreign and external
stand-ins) and the contract they implement; only ``runtime/`` touches a transport.

MuJoCo reads MUJOCO_GL when it is first imported, and the camera renders headless through
EGL, so the default is set here, before any module of a node kind imports mujoco. A user
may still choose another backend (osmesa, glfw) by exporting MUJOCO_GL.

Importing this package provides its node kinds to the plan (``nodes.registry``).
"""

import os

os.environ.setdefault("MUJOCO_GL", "egl")

import nodes.registry  # noqa: E402, F401 - provides the catalogue of kinds to plan.kinds
