"""Which GL renderer draws a run's rendered topics, for the manifest's ``digest_versions``.

A fresh interpreter makes a 1 x 1 MuJoCo GL context (``MUJOCO_GL``, as the camera nodes get
it) and reads GL_VENDOR, GL_RENDERER and GL_VERSION: about 0.4 CPU s of software GL set-up,
which was paid again at every run with a camera. The answer depends only on the GL libraries
the dynamic loader finds, the drivers they load and the environment that chooses among them,
so it is kept per user, keyed by those: the paths, sizes and modification times of the GL and
LLVM libraries (``ldconfig -p``) and of Mesa's DRI drivers, the variables that pick a GL
(MUJOCO_GL, PYOPENGL_PLATFORM, Mesa's, EGL's, DRI_PRIME, the display, the library path), the
mujoco version, and this boot of this host (``boot_id``: llvmpipe's string names the CPU's
vector width, and a home shared between hosts must not share answers). An upgraded Mesa,
LLVM or driver, another backend or a reboot probes again. Where the key cannot be made (no
ldconfig), every run probes, as before.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import platform
import re
import shutil
import subprocess
import sys
from importlib import metadata
from pathlib import Path

PROBE_TIMEOUT_S = 60
_PROBE = """
import mujoco
from OpenGL import GL
ctx = mujoco.GLContext(1, 1)
ctx.make_current()
print(" | ".join(GL.glGetString(k).decode() for k in (GL.GL_VENDOR, GL.GL_RENDERER,
                                                     GL.GL_VERSION)))
ctx.free()
"""
GL_LIBRARY = re.compile(
    r"^\s*(lib(?:EGL|GL|gallium|glapi|OSMesa|nvidia|LLVM)\S*)\s.*=>\s*(\S+)\s*$")
GL_VARIABLES = re.compile(r"^(MUJOCO_|PYOPENGL_|MESA_|LIBGL_|GALLIUM_|EGL_|__EGL|__GLX|LP_|"
                          r"DRI_|DISPLAY$|WAYLAND_DISPLAY$|LD_LIBRARY_PATH$|LD_PRELOAD$)")
DRI_FOLDERS = ("/usr/lib/x86_64-linux-gnu/dri", "/usr/lib64/dri", "/usr/lib/dri")
BOOT_ID = Path("/proc/sys/kernel/random/boot_id")
_answers: dict[str, str] = {}  # this process's probes, by key (a sweep's worker runs many)


class RendererProbe:
    """The renderer of this machine and environment: from the cache when it has the key, else
    from a probe started now (it overlaps the run) and read when the manifest is written."""

    def __init__(self) -> None:
        env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
        if env["MUJOCO_GL"] == "egl":
            env.setdefault("PYOPENGL_PLATFORM", "egl")
        self.backend = env["MUJOCO_GL"]
        self._key = renderer_key(env)
        self._answer: str | None = cached_answer(self._key)
        self._proc: subprocess.Popen | None = None
        if self._answer is not None:
            return
        try:
            self._proc = subprocess.Popen(
                [sys.executable, "-c", _PROBE], stdout=subprocess.PIPE,
                stderr=subprocess.PIPE, stdin=subprocess.DEVNULL, text=True, env=env)
        except OSError as exc:
            self._answer = f"unknown ({exc})"

    def result(self) -> str:
        """'egl: vendor | renderer | GL version', or 'unknown (why)'."""
        if self._answer is None and self._proc is not None:
            try:
                out, err = self._proc.communicate(timeout=PROBE_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                self._proc.kill()
                self._proc.communicate()
                out, err = "", "the probe did not answer in time"
            lines = out.strip().splitlines()
            if self._proc.returncode or not lines:
                self._answer = f"unknown ({(err.strip().splitlines() or ['no output'])[-1][:200]})"
            else:
                self._answer = f"{self.backend}: {lines[-1]}"
                keep_answer(self._key, self._answer)
        return self._answer or "unknown"


def renderer_key(env: dict[str, str]) -> str | None:
    """What the probe's answer depends on, hashed; None when the GL libraries cannot be
    listed (then nothing is cached)."""
    libraries = gl_libraries()
    if libraries is None:
        return None
    try:
        mujoco_version = metadata.version("mujoco")
    except metadata.PackageNotFoundError:
        mujoco_version = "not installed"
    variables = {k: v for k, v in sorted(env.items()) if GL_VARIABLES.match(k)}
    folders = [*env.get("LIBGL_DRIVERS_PATH", "").split(os.pathsep), *DRI_FOLDERS]
    text = json.dumps([libraries, dri_drivers(tuple(f for f in folders if f)), variables,
                       mujoco_version, sys.executable, this_boot()])
    return hashlib.sha256(text.encode()).hexdigest()[:32]


@functools.lru_cache(maxsize=1)
def gl_libraries() -> list[tuple[str, str, int, int]] | None:
    """(name, file, size, mtime ns) of every GL library the loader's cache lists; None
    without ldconfig."""
    ldconfig = shutil.which("ldconfig") or next(
        (p for p in ("/sbin/ldconfig", "/usr/sbin/ldconfig") if os.access(p, os.X_OK)), None)
    if ldconfig is None:
        return None
    try:
        listing = subprocess.run([ldconfig, "-p"], capture_output=True, text=True, timeout=10,
                                 check=True).stdout
    except (OSError, subprocess.SubprocessError):
        return None
    found = []
    for line in listing.splitlines():
        match = GL_LIBRARY.match(line)
        if match:
            path = os.path.realpath(match.group(2))
            try:
                stat = os.stat(path)
            except OSError:
                continue
            found.append((match.group(1), path, stat.st_size, stat.st_mtime_ns))
    return sorted(found)


@functools.lru_cache(maxsize=4)
def dri_drivers(folders: tuple[str, ...]) -> list[tuple[str, int, int]]:
    """(file, size, mtime ns) of the DRI drivers in ``folders`` (Mesa's renderers)."""
    found = []
    for folder in folders:
        try:
            entries = sorted(os.scandir(folder), key=lambda e: e.name)
        except OSError:
            continue
        for entry in entries:
            if entry.name.endswith(".so"):
                try:
                    stat = entry.stat()
                except OSError:
                    continue
                found.append((entry.path, stat.st_size, stat.st_mtime_ns))
    return found


def this_boot() -> str:
    """This host and boot: the kernel's boot id, else the host name."""
    try:
        return BOOT_ID.read_text().strip()
    except OSError:
        return platform.node()


def _cache_file(key: str) -> Path:
    from descriptions.mesh_convert import cache_dir

    return cache_dir("renderers") / key


def cached_answer(key: str | None) -> str | None:
    """The answer kept for ``key`` (this process's, else the user's cache), if any."""
    if key is None:
        return None
    if key in _answers:
        return _answers[key]
    try:
        answer = _cache_file(key).read_text().strip()
    except OSError:
        return None
    if answer:
        _answers[key] = answer
    return answer or None


def keep_answer(key: str | None, answer: str) -> None:
    """Keep a probe's answer under ``key`` (written whole or not at all)."""
    if key is None:
        return
    _answers[key] = answer
    from descriptions.mesh_convert import write_atomic

    try:
        write_atomic(_cache_file(key), answer.encode())
    except OSError:
        pass  # the next run probes again
