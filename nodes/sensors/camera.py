"""An RGB-D camera rendered headless with mujoco.Renderer (EGL; see nodes/sensors/__init__.py).

Colour is rgb8, depth is 32FC1 in metres. MuJoCo's Renderer already returns linear z-depth
(distance along the optical axis, not along the ray), which is what REP-118 depth images
hold; pixels with nothing within ``max_depth`` read +inf. Both images share one optical
frame (REP-103: z forward, x right, y down), default ``camera_color_optical_frame``.
Intrinsics follow from the MuJoCo camera's vertical field of view with square pixels:
fx = fy = (h/2) / tan(fovy/2), and the principal point is the image centre in OpenCV pixel
coordinates (pixel centres at integers): cx = (w-1)/2, cy = (h-1)/2.
Shadows, reflections and the skybox are switched off to keep software rendering cheap.
"""

from __future__ import annotations

import math
import os
import signal
import threading

import mujoco
import numpy as np
from pydantic import BaseModel, ConfigDict, Field
from sensor_msgs.msg import CameraInfo, Image

from nodes.physics.world import named_id
from nodes.sensors.mirror import WorldMirror, group_mask

COLOR_TOPIC = "/camera/color/image_raw"
DEPTH_TOPIC = "/camera/depth/image_rect"
INFO_TOPIC = "/camera/camera_info"


class CameraParams(BaseModel):
    """Which MJCF camera to render, the image size, depth range and visible geom groups."""

    model_config = ConfigDict(extra="forbid")
    camera: str | None = Field(None, description="the MJCF camera; default: the robot "
                               "model's (descriptions.robot_reader)")
    frame_id: str | None = Field(None, description="its optical frame; default: the robot "
                                 "model's")
    width: int = Field(160, ge=8, le=640)
    height: int = Field(120, ge=8, le=480)
    depth: bool = True
    max_depth: float = Field(10.0, gt=0)
    geom_groups: list[int] = [0, 1, 2]


def intrinsics(width: int, height: int, fovy_deg: float) -> tuple[float, float, float]:
    """(f, cx, cy) of a pinhole with square pixels and vertical field of view ``fovy_deg``."""
    f = (height / 2) / math.tan(math.radians(fovy_deg) / 2)
    return f, (width - 1) / 2, (height - 1) / 2


class RgbdCamera:
    """Renders colour and depth images of the mirrored world and their CameraInfo."""

    def __init__(self, mirror: WorldMirror, params: CameraParams, warm_up: bool = True):
        self.mirror = mirror
        self.params = params
        model = mirror.model
        self.cam = named_id(model, mujoco.mjtObj.mjOBJ_CAMERA, params.camera)
        model.vis.global_.offwidth = max(model.vis.global_.offwidth, params.width)
        model.vis.global_.offheight = max(model.vis.global_.offheight, params.height)
        self._renderer: mujoco.Renderer | None = None  # see the renderer property
        self.option = mujoco.MjvOption()
        self.option.geomgroup[:] = group_mask(params.geom_groups)
        self.info = self._camera_info(float(model.cam_fovy[self.cam]))
        self._warming: threading.Thread | None = None
        self._warm_result: mujoco.Renderer | BaseException | None = None
        # warm_up=False (run option camera_warm_up) makes the renderer at the first render
        if os.environ.get("MUJOCO_GL") == "egl" and warm_up:
            # not a daemon: an exiting interpreter waits for it before its atexit handlers
            # tear EGL down (mujoco.egl registers one), which must not run under it
            self._warming = threading.Thread(target=self._warm_up, name="camera-gl")
            self._warming.start()

    def _camera_info(self, fovy: float) -> CameraInfo:
        p = self.params
        f, cx, cy = intrinsics(p.width, p.height, fovy)
        info = CameraInfo()
        info.header.frame_id = p.frame_id
        info.width, info.height = p.width, p.height
        info.distortion_model = "plumb_bob"
        info.d = [0.0] * 5
        info.k = [f, 0.0, cx, 0.0, f, cy, 0.0, 0.0, 1.0]
        info.r = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
        info.p = [f, 0.0, cx, 0.0, 0.0, f, cy, 0.0, 0.0, 0.0, 1.0, 0.0]
        return info

    @property
    def renderer(self) -> mujoco.Renderer:
        """The GL renderer. Setting up an EGL context and compiling the shaders (llvmpipe
        compiles them at the first frame) takes 0.4-1 s in software; done at the first
        activation it held the whole run up, since the other nodes may run only a window of
        ticks ahead of a camera. So the camera starts it in a thread of its own when it is
        built, on a world state of its own, and the first render only waits for what is
        left of it. Same pixels either way (the warm-up frame is thrown away)."""
        if self._renderer is None:
            made = self._finish_warm_up()
            if isinstance(made, BaseException):
                raise RuntimeError(f"the camera's GL renderer failed: {made}") from made
            self._renderer = made if made is not None else self._make_renderer()
        return self._renderer

    def _finish_warm_up(self) -> mujoco.Renderer | BaseException | None:
        """Wait for the warm-up thread, if one runs, and take what it made (or why not)."""
        if self._warming is None:
            return None
        self._warming.join()
        self._warming, made, self._warm_result = None, self._warm_result, None
        return made

    def _make_renderer(self) -> mujoco.Renderer:
        p = self.params
        renderer = mujoco.Renderer(self.mirror.model, p.height, p.width)
        for flag in (mujoco.mjtRndFlag.mjRND_SHADOW, mujoco.mjtRndFlag.mjRND_REFLECTION,
                     mujoco.mjtRndFlag.mjRND_SKYBOX):
            renderer.scene.flags[flag] = 0
        return renderer

    def _warm_up(self) -> None:
        """In the warm-up thread: make the renderer, render one frame of each kind from a
        world state of its own, then release the EGL context for the thread that renders."""
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGALRM})  # alarms are the step's
        try:
            renderer = self._make_renderer()
            data = mujoco.MjData(self.mirror.model)
            mujoco.mj_forward(self.mirror.model, data)
            renderer.update_scene(data, camera=self.cam, scene_option=self.option)
            renderer.render()
            if self.params.depth:
                renderer.enable_depth_rendering()
                renderer.render()
                renderer.disable_depth_rendering()
            _release_egl_context()
            self._warm_result = renderer
        except BaseException as exc:  # handed to the first render, which raises it
            self._warm_result = exc

    def render(self) -> tuple[Image, Image | None, CameraInfo]:
        """(colour, depth or None, camera info) of the mirrored world now."""
        r = self.renderer
        if r.model is not self.mirror.model:  # an event changed the world
            r = self._follow_world(r)
        r.update_scene(self.mirror.data, camera=self.cam, scene_option=self.option)
        rgb = r.render()
        depth_msg = None
        if self.params.depth:
            r.enable_depth_rendering()
            depth = r.render()
            r.disable_depth_rendering()
            depth = np.where(depth < self.params.max_depth, depth, np.inf).astype(np.float32)
            depth_msg = self._image(depth, "32FC1", 4)
        return self._image(rgb, "rgb8", 3), depth_msg, self.info

    def _follow_world(self, renderer: mujoco.Renderer) -> mujoco.Renderer:
        """The renderer for the mirror's new model. Objects of MuJoCo's own shapes need
        nothing of the GL context, so a context made for a model with the same meshes,
        textures, height fields and skins draws the new one as it is (no new context: that
        costs 0.4-1 s in software); a new mesh needs a new context."""
        model, old = self.mirror.model, renderer.model
        model.vis.global_.offwidth = max(model.vis.global_.offwidth, self.params.width)
        model.vis.global_.offheight = max(model.vis.global_.offheight, self.params.height)
        assets = ("nmesh", "nmeshvert", "ntex", "ntexdata", "nhfield", "nskin", "nflex")
        if (all(getattr(model, a) == getattr(old, a) for a in assets)
                and np.array_equal(model.mesh_vert, old.mesh_vert)):
            renderer._model = model  # noqa: SLF001 - Renderer has no setter; same context
            return renderer
        renderer.close()
        self._renderer = self._make_renderer()
        return self._renderer

    def _image(self, pixels: np.ndarray, encoding: str, bytes_per_pixel: int) -> Image:
        msg = Image()
        msg.header.frame_id = self.params.frame_id
        msg.height, msg.width = pixels.shape[:2]
        msg.encoding = encoding
        msg.is_bigendian = 0
        msg.step = msg.width * bytes_per_pixel
        msg.data = np.ascontiguousarray(pixels).tobytes()
        return msg

    def close(self) -> None:
        """Release the GL context (if one was made)."""
        made = self._finish_warm_up()
        if isinstance(made, mujoco.Renderer):
            self._renderer = made
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


def _release_egl_context() -> None:
    """Make no EGL context current on this thread, so that another thread can take it."""
    from mujoco import egl

    egl.EGL.eglMakeCurrent(egl.EGL_DISPLAY, egl.EGL.EGL_NO_SURFACE, egl.EGL.EGL_NO_SURFACE,
                           egl.EGL.EGL_NO_CONTEXT)
    egl.EGL.eglReleaseThread()
