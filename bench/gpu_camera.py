"""Offscreen camera cost: MuJoCo RGB and depth renders of the nav world at four image sizes.

Standalone (mujoco and numpy only, no cosim imports), so that it runs where cosim is not
installed, e.g. on a GPU machine. It loads the world named by ``scenarios/nav.yaml``
(``world:``), puts the robot at the scenario's start pose, renders from the first camera
of the model (the robot's ``rgbd``; a free camera if the model has none) with the camera
node's settings (geom groups 0-2, no shadows, reflections or skybox) and reports, for each
size, the time to create the renderer (GL context), the first frame, and the mean ms per
frame of RGB and of depth renders (``update_scene`` + ``render``, read-back included).
The GL vendor and renderer strings show whether a GPU or software rendering was used.

Here (Mesa software EGL)::

    .venv/bin/python bench/gpu_camera.py

On a GPU machine with Python 3.12 but no mujoco and no network, carry the wheels
(mujoco, mujoco-core, mujoco-studio, websockets, PyOpenGL, glfw, downloaded here with
``pip download --only-binary=:all: --python-version 3.12 --platform manylinux_2_28_x86_64
--no-deps -d .gpuwheels ...``) and the glvnd EGL loader debs (``.gl``), then run::

    for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
    python3 -m pip install -q --no-index --no-deps --target /tmp/site .gpuwheels/*.whl
    PYTHONPATH=/tmp/site MUJOCO_GL=egl python3 bench/gpu_camera.py

(if no EGL driver is found, also export
``__EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json``).
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")  # before mujoco is imported

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "nav.yaml"
SIZES = [(160, 120), (320, 240), (640, 480), (1280, 960)]
START = (-3.0, -3.0, 0.785)  # nav.yaml's physics start pose: x, y (m), yaw (rad)


def world_path(scenario: Path) -> Path:
    """The world file named by the scenario's top-level ``world:`` key (relative to it)."""
    for line in scenario.read_text().splitlines():
        if line.startswith("world:"):
            value = line.split(":", 1)[1].split("#", 1)[0].strip().strip("'\"")
            return (scenario.parent / value).resolve()
    raise ValueError(f"no 'world:' key in {scenario}")


def load_world(path: Path, max_w: int, max_h: int) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The model with an offscreen buffer of at least ``max_w`` x ``max_h`` and its data,
    the robot (first free joint) placed at the nav start pose and kinematics computed."""
    model = mujoco.MjModel.from_xml_path(str(path))
    model.vis.global_.offwidth = max(model.vis.global_.offwidth, max_w)
    model.vis.global_.offheight = max(model.vis.global_.offheight, max_h)
    data = mujoco.MjData(model)
    free = [j for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE]
    if free:
        adr = model.jnt_qposadr[free[0]]
        x, y, yaw = START
        data.qpos[adr:adr + 2] = x, y
        data.qpos[adr + 3:adr + 7] = np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)
    mujoco.mj_forward(model, data)
    return model, data


def gl_strings() -> dict[str, str]:
    """GL vendor, renderer and version of the current context (empty if unavailable)."""
    try:
        from OpenGL import GL

        return {name: GL.glGetString(getattr(GL, f"GL_{name.upper()}")).decode()
                for name in ("vendor", "renderer", "version")}
    except Exception as exc:  # only informative: never fail the benchmark on it
        return {"error": f"{type(exc).__name__}: {exc}"}


def make_renderer(model: mujoco.MjModel, width: int, height: int) -> mujoco.Renderer:
    """A renderer with the camera node's scene flags (no shadow, reflection, skybox)."""
    r = mujoco.Renderer(model, height, width)
    for flag in (mujoco.mjtRndFlag.mjRND_SHADOW, mujoco.mjtRndFlag.mjRND_REFLECTION,
                 mujoco.mjtRndFlag.mjRND_SKYBOX):
        r.scene.flags[flag] = 0
    return r


def measure(model: mujoco.MjModel, data: mujoco.MjData, camera: int | mujoco.MjvCamera,
            width: int, height: int, frames: int, warmup: int) -> dict:
    """Times in ms for one size: renderer creation, first RGB frame, mean RGB and depth
    frames (``warmup`` untimed frames before ``frames`` timed ones), plus image checks."""
    option = mujoco.MjvOption()
    option.geomgroup[:] = [1, 1, 1, 0, 0, 0]

    def frame() -> np.ndarray:
        r.update_scene(data, camera=camera, scene_option=option)
        return r.render()

    def first_then_mean() -> tuple[float, float, np.ndarray]:
        """ms of the first frame, mean ms of ``frames`` after ``warmup`` more, last image."""
        t = time.perf_counter()
        image = frame()
        first = (time.perf_counter() - t) * 1e3
        for _ in range(warmup):
            frame()
        t = time.perf_counter()
        for _ in range(frames):
            image = frame()
        return first, (time.perf_counter() - t) / frames * 1e3, image

    t0 = time.perf_counter()
    r = make_renderer(model, width, height)
    out = {"context_ms": (time.perf_counter() - t0) * 1e3}
    out["first_ms"], out["rgb_ms"], rgb = first_then_mean()
    r.enable_depth_rendering()
    out["first_depth_ms"], out["depth_ms"], depth = first_then_mean()
    r.disable_depth_rendering()
    out["rgb_mean"] = float(rgb.mean())
    out["depth_median_m"] = float(np.median(depth))
    out["gl"] = gl_strings()  # the context is current while the renderer lives
    r.close()
    return out


def main() -> None:
    """Parse arguments, load the world and print the timing table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--world", type=Path, default=None, help="MJCF file (default: nav's)")
    ap.add_argument("--frames", type=int, default=50)
    ap.add_argument("--warmup", type=int, default=5)
    ap.add_argument("--sizes", default=",".join(f"{w}x{h}" for w, h in SIZES),
                    help="comma-separated WxH list")
    args = ap.parse_args()
    sizes = [tuple(int(v) for v in s.split("x")) for s in args.sizes.split(",")]
    path = args.world or world_path(SCENARIO)
    model, data = load_world(path, max(w for w, _ in sizes), max(h for _, h in sizes))
    if model.ncam:
        camera: int | mujoco.MjvCamera = 0
        cam_name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_CAMERA, 0) or "camera 0"
    else:
        camera = mujoco.MjvCamera()
        mujoco.mjv_defaultFreeCamera(model, camera)
        cam_name = "free camera"
    print(f"mujoco {mujoco.__version__}, MUJOCO_GL={os.environ.get('MUJOCO_GL')}, "
          f"world {path.relative_to(ROOT) if path.is_relative_to(ROOT) else path}, "
          f"camera {cam_name}, {args.frames} frames after {args.warmup} warm-up")
    rows = []
    gl = None
    for w, h in sizes:
        res = measure(model, data, camera, w, h, args.frames, args.warmup)
        gl = gl or res["gl"]
        rows.append((w, h, res))
    print("GL: " + "; ".join(f"{k}={v}" for k, v in (gl or {}).items()))
    print(f"{'size':>10} {'context ms':>11} {'first ms':>9} {'RGB ms':>8} {'depth ms':>9} "
          f"{'1st depth':>10} {'rgb mean':>9} {'depth med m':>12}")
    for w, h, r in rows:
        print(f"{w:>5}x{h:<4} {r['context_ms']:>11.1f} {r['first_ms']:>9.1f} "
              f"{r['rgb_ms']:>8.2f} {r['depth_ms']:>9.2f} {r['first_depth_ms']:>10.1f} "
              f"{r['rgb_mean']:>9.1f} {r['depth_median_m']:>12.3f}")


if __name__ == "__main__":
    main()
