"""cosim sensors node.

MuJoCo reads MUJOCO_GL when it is first imported, and the camera renders headless through
EGL, so the default is set here, before any module of this package imports mujoco. A user
may still choose another backend (osmesa, glfw) by exporting MUJOCO_GL.
"""

import os

os.environ.setdefault("MUJOCO_GL", "egl")
