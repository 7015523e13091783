"""cosim's processes load their own ROS 2 libraries, whatever environment they inherit.

The ROS 2 wheels find their shared libraries (and those cosim builds into ``<venv>/lib``,
which rclpy's type support dlopens by name) through ``LD_LIBRARY_PATH``: their start-up hook
(``ros_wheels_bootstrapper.pth``) re-executes every venv Python once with ``<venv>/lib`` and
``site-packages/ros_*.libs`` added, and sets ``_ROS_WHEELS_BOOTSTRAP_COMPLETE`` so that it
happens once. A process started by another Python that bootstrapped its own wheels inherits
that flag and the other venv's ``LD_LIBRARY_PATH``: the hook then does nothing, and rclpy
loads the other venv's libraries or none (``librcl_action.so: cannot open``,
``libtf2_msgs__rosidl_typesupport_fastrtps_c.so``). A sourced ``/opt/ros`` setup does the
same harm, since the hook adds its directories in no particular order.

The dynamic loader reads ``LD_LIBRARY_PATH`` once, at process start, so the only cure is the
hook's own: each cosim command checks it first thing and, unless this venv's directories
lead it, executes itself again with them first (what was inherited follows them, for
programs that need it). Its children inherit the corrected environment.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Mapping
from pathlib import Path

BOOTSTRAP_FLAG = "_ROS_WHEELS_BOOTSTRAP_COMPLETE"  # the wheels' hook's guard


def own_library_dirs() -> list[str]:
    """The directories this venv's ROS 2 libraries live in, as the wheels' hook finds them:
    ``<prefix>/lib`` and each ``site-packages/ros_*.libs`` (sorted)."""
    version = f"python{sys.version_info.major}.{sys.version_info.minor}"
    site = Path(sys.prefix, "lib", version, "site-packages")
    libs = sorted(str(p.resolve()) for p in site.glob("ros_*.libs") if p.is_dir())
    return [os.path.join(sys.prefix, "lib"), *libs]


def fixed_library_path(env: Mapping[str, str], own: list[str]) -> str | None:
    """The ``LD_LIBRARY_PATH`` a cosim process needs: ``own`` first, then what ``env`` had
    (without repeats); None when ``env``'s already starts with ``own`` (in any order)."""
    current = [p for p in env.get("LD_LIBRARY_PATH", "").split(os.pathsep) if p]
    mine = {os.path.realpath(p) for p in own}
    if {os.path.realpath(p) for p in current[:len(own)]} == mine:
        return None
    rest = [p for p in current if os.path.realpath(p) not in mine]
    return os.pathsep.join([*own, *dict.fromkeys(rest)])


def ensure_own_libraries() -> None:
    """Execute this command again with this venv's ROS 2 libraries first on the library
    path, when the environment it inherited does not have them there (no return then)."""
    own = own_library_dirs()
    if len(own) < 2:  # no ROS 2 wheels with libraries here: nothing to put first
        return
    fixed = fixed_library_path(os.environ, own)
    if fixed is None:
        return
    env = {**os.environ, "LD_LIBRARY_PATH": fixed, BOOTSTRAP_FLAG: "1"}
    sys.stdout.flush()
    sys.stderr.flush()
    os.execve(sys.executable, sys.orig_argv, env)
