"""A robot's TF tree, the transforms of /tf and /tf_static (REP-105): one ``RobotFrames``
for every robot, made by ``mjcf_frames`` for an MJCF robot (its bodies and the frames its
robot model hangs on its sites and cameras, as below) or by
``nodes.physics.described_rig.DescribedRobot.frames`` for a described one (URDF, xacro, USD:
a transform per joint of its robot model, under its link names, as robot_state_publisher
sends them). An MJCF robot's:

- ``map -> odom``: a fixed offset (``tf.map_to_odom``, identity by default), sent on /tf at
  every tick like the transform a localization node (AMCL, slam_toolbox) publishes, so that
  one can take over by setting ``tf.map_frame: null``.
- ``odom -> base_link``: the robot's free joint, the very pose /odom carries.
- Under ``base_link`` every body on the way to a sensor or to a position-servoed joint (the
  pan-tilt head, an arm's links) is a frame named after its body. A
  body that moves on a joint (the pan-tilt head: ``pan_link``, ``tilt_link``) is sent on /tf
  at every tick, as robot_state_publisher would from /joint_states; a rigid one on /tf_static.
- Each sensor frame hangs off its body, on /tf_static: a site (the lidar's ``laser``, the
  IMU's ``imu_link``) at the site's pose; a camera as ``camera_link`` (REP-103 body axes: x
  forward, y left, z up) and its optical frames ``camera_color_optical_frame`` and
  ``camera_depth_optical_frame`` (REP-103 optical axes: z forward, x right, y down), at the
  camera's origin: MuJoCo renders colour and depth from one viewpoint, so the depth image is
  registered to the colour one.

Stamps are left to the runtime, which stamps every transform of a TFMessage with the tick's
time (runtime.exchange.prepare_outputs).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from geometry_msgs.msg import TransformStamped
from pydantic import BaseModel, ConfigDict

from descriptions.robot_model import CameraLink, RobotModel
from plan.rot3 import mat_mul, mat_t_mul, mat_t_vec

BODY = mujoco.mjtObj.mjOBJ_BODY
SITE = mujoco.mjtObj.mjOBJ_SITE
CAMERA = mujoco.mjtObj.mjOBJ_CAMERA
JOINT = mujoco.mjtObj.mjOBJ_JOINT

# Axes of camera_link and of the optical frames in MuJoCo's camera frame (x right, y up,
# looking along -z): the columns are each frame's x, y, z.
LINK_IN_CAMERA = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0]])
OPTICAL_IN_CAMERA = np.diag([1.0, -1.0, -1.0])


class CameraFrames(BaseModel):
    """An MJCF camera and the names of its frames."""

    model_config = ConfigDict(extra="forbid")
    camera: str = "rgbd"
    link_frame: str = "camera_link"
    color_optical_frame: str = "camera_color_optical_frame"
    depth_optical_frame: str = "camera_depth_optical_frame"


class MapToOdom(BaseModel):
    """The fixed offset of odom in map: position in metres, heading in radians."""

    model_config = ConfigDict(extra="forbid")
    x: float = 0.0
    y: float = 0.0
    yaw: float = 0.0


class TfParams(BaseModel):
    """Which frames the physics node sends on /tf and /tf_static (see the module docstring)."""

    model_config = ConfigDict(extra="forbid")
    map_frame: str | None = "map"
    map_to_odom: MapToOdom = MapToOdom()
    sites: dict[str, str] = {"laser": "laser"}  # MJCF site -> frame name
    cameras: list[CameraFrames] = [CameraFrames()]
    # sites and cameras name what an MJCF robot's model is read with (its site_frames and
    # camera_frames: PhysicsNode.description_names); its frames are taken off the model


@dataclass(frozen=True)
class MovingBody:
    """A body on a joint whose transform from its parent is sent at every tick."""

    body: int
    parent: int
    parent_frame: str
    frame: str


def transform(parent: str, child: str, pos, quat_wxyz) -> TransformStamped:
    """A TransformStamped (stamp left to the runtime) from a position and a MuJoCo quaternion."""
    msg = TransformStamped()
    msg.header.frame_id = parent
    msg.child_frame_id = child
    t, r = msg.transform.translation, msg.transform.rotation
    t.x, t.y, t.z = (float(v) for v in pos)
    r.w, r.x, r.y, r.z = (float(v) for v in quat_wxyz)
    return msg


def quat_of(mat: np.ndarray) -> np.ndarray:
    """The MuJoCo quaternion (w, x, y, z) of a rotation matrix, with w >= 0."""
    quat = np.empty(4)
    mujoco.mju_mat2Quat(quat, np.asarray(mat, dtype=np.float64).ravel())
    return -quat if quat[0] < 0 else quat


def frame_problems(model: mujoco.MjModel, params: TfParams, base_body: str,
                   extra_sites: dict[str, str]) -> list[tuple[str, str, str]]:
    """What in ``params`` the world cannot give: (key, problem, accepted) per problem."""
    base = mujoco.mj_name2id(model, BODY, base_body)
    sites = {**params.sites, **extra_sites}
    for site, _ in sites.items():
        sid = mujoco.mj_name2id(model, SITE, site)
        key = "params.tf.sites" if site in params.sites else "params.imu.site"
        if sid < 0:
            names = [model.site(i).name for i in range(model.nsite)]
            return [(key, f"the world has no site {site!r}; its sites: "
                     f"{', '.join(names) or 'none'}.", "sites of the robot in the world.")]
        if not on_robot(model, int(model.site_bodyid[sid]), base):
            return [(key, f"site {site!r} is not on the robot's body tree.",
                     f"a site under body {base_body!r}.")]
    for n, cam in enumerate(params.cameras):
        cid = mujoco.mj_name2id(model, CAMERA, cam.camera)
        key = f"params.tf.cameras[{n}].camera"
        if cid < 0:
            names = [model.camera(i).name for i in range(model.ncam)]
            return [(key, f"the world has no camera {cam.camera!r}; its cameras: "
                     f"{', '.join(names) or 'none'}.", "a camera of the robot in the world.")]
        if not on_robot(model, int(model.cam_bodyid[cid]), base):
            return [(key, f"camera {cam.camera!r} is not on the robot's body tree.",
                     f"a camera under body {base_body!r}.")]
    return []


def on_robot(model: mujoco.MjModel, body: int, base: int) -> bool:
    """Whether ``body`` is ``base`` or under it."""
    while body != base and body > 0:
        body = int(model.body_parentid[body])
    return body == base


class RobotFrames:
    """Every robot's TF, whatever describes it: the static transforms (computed once, for
    /tf_static) and, per state, ``map -> odom``, ``odom -> base`` (where ``publishes_base``),
    the moving bodies (pairs of bodies, batched by nodes.physics.batch: an MJCF robot's
    bodies on a joint, a described robot's moving joints) and the moving links read per
    robot by ``link_frames`` (an object with ``has_moving`` and ``moving(data)``; only a
    described robot's joint with an end on a world site has one).

    ``mjcf_frames`` makes one for an MJCF robot (frames named after its bodies, sites and
    cameras), ``nodes.physics.described_rig.DescribedRobot.frames`` for a described one (URDF,
    xacro, USD: frames named after its links)."""

    def __init__(self, params: TfParams, odom_frame: str, base_frame: str,
                 static: list[TransformStamped], moving: list[MovingBody] | None = None,
                 link_frames=None, publishes_base: bool = True):
        self.odom_frame, self.base_frame = odom_frame, base_frame
        self.static = static
        self.moving = moving or []
        self.link_frames = link_frames
        self.publishes_base = publishes_base
        m = params.map_to_odom
        self.map_to_odom = (None if params.map_frame is None else
                            (params.map_frame, (m.x, m.y, 0.0),
                             (np.cos(m.yaw / 2), 0.0, 0.0, np.sin(m.yaw / 2))))

    @property
    def needs_kinematics(self) -> bool:
        """Whether any transform depends on body positions (a moving body or link)."""
        return bool(self.moving) or (self.link_frames is not None and
                                     self.link_frames.has_moving)

    def links(self, data: mujoco.MjData) -> list[TransformStamped]:
        """The moving links' transforms, parent link -> child link (none without
        ``link_frames``)."""
        if self.link_frames is None:
            return []
        return [transform(t.parent, t.child, t.pos, t.quat)
                for t in self.link_frames.moving(data)]

    def dynamic(self, data: mujoco.MjData, base_qpos: np.ndarray) -> list[TransformStamped]:
        """map -> odom, odom -> base (from the free joint's ``base_qpos``), the moving
        bodies and the moving links (from ``data``'s current kinematics); what
        nodes.physics.batch sends for every robot at once."""
        out = []
        if self.map_to_odom is not None:
            frame, pos, quat = self.map_to_odom
            out.append(transform(frame, self.odom_frame, pos, quat))
        if self.publishes_base:
            out.append(transform(self.odom_frame, self.base_frame, base_qpos[:3],
                                 base_qpos[3:7]))
        conj = np.empty(4)
        quat = np.empty(4)
        for m in self.moving:
            pos = mat_t_vec(data.xmat[m.parent], data.xpos[m.body] - data.xpos[m.parent])
            mujoco.mju_negQuat(conj, data.xquat[m.parent])
            mujoco.mju_mulQuat(quat, conj, data.xquat[m.body])
            out.append(transform(m.parent_frame, m.frame, pos, quat))
        return out + self.links(data)


def mjcf_frames(model: mujoco.MjModel, params: TfParams, robot: RobotModel, odom_frame: str,
                extra_sites: dict[str, str]) -> RobotFrames:
    """The frames of an MJCF robot, as its model names them: under its base link every body
    on the way to a frame on a site (its ``site_frames``, then ``extra_sites``: the IMU's,
    site -> frame), a camera (its ``camera_frames``) or a commanded joint, each body's frame
    named after it (``RobotModel.frame``: its MuJoCo prefix swapped for its frame prefix).
    ``odom -> base`` is sent for a base fixed to the world too; of ``params`` only
    map -> odom counts."""
    chain = _BodyChain(model, mujoco.mj_name2id(model, BODY, robot.base), robot.base_link,
                       robot.frame)
    sites = {link.site: link.name for link in robot.site_frames}
    for site, frame in {**sites, **extra_sites}.items():
        sid = mujoco.mj_name2id(model, SITE, site)
        body = int(model.site_bodyid[sid])
        chain.add(body)
        chain.static.append(transform(chain.frame_of(body), frame, model.site_pos[sid],
                                      model.site_quat[sid]))
    for cam in robot.camera_frames:
        chain.camera(cam)
    for a in robot.actuated:  # the links the robot's servos move (an arm's whole chain)
        chain.add(int(model.jnt_bodyid[mujoco.mj_name2id(model, JOINT, a.joint)]))
    return RobotFrames(params, odom_frame, robot.base_link, chain.static, chain.moving)


class _BodyChain:
    """The transforms from an MJCF robot's base body down to the bodies added: rigid ones
    static, those on a joint moving; each body once, parents first."""

    def __init__(self, model: mujoco.MjModel, base: int, base_frame: str, body_frame):
        self.model, self.base, self.base_frame, self.body_frame = (model, base, base_frame,
                                                                   body_frame)
        self.static: list[TransformStamped] = []
        self.moving: list[MovingBody] = []
        self._done: set[int] = set()

    def frame_of(self, body: int) -> str:
        """The TF frame of ``body``: the base frame, or the body's (renamed) name."""
        return (self.base_frame if body == self.base
                else self.body_frame(self.model.body(body).name))

    def add(self, body: int) -> None:
        """Add the transforms from the base body down to ``body``."""
        model = self.model
        path = []
        while body != self.base and body not in self._done:
            self._done.add(body)
            path.append(body)
            body = int(model.body_parentid[body])
        for body in reversed(path):
            parent = int(model.body_parentid[body])
            name = model.body(body).name
            if name:
                name = self.body_frame(name)
            if not name:
                raise ValueError(f"body {body} on the way to a sensor frame has no name; "
                                 "name it in the MJCF (it becomes a TF frame)")
            if model.body_jntnum[body]:
                self.moving.append(MovingBody(body, parent, self.frame_of(parent), name))
            else:
                self.static.append(transform(self.frame_of(parent), name,
                                             model.body_pos[body], model.body_quat[body]))

    def camera(self, cam: CameraLink) -> None:
        """Add a camera's link and optical frames (and the bodies down to it)."""
        model = self.model
        cid = mujoco.mj_name2id(model, CAMERA, cam.camera)
        body = int(model.cam_bodyid[cid])
        self.add(body)
        cam_in_body = np.empty(9)
        mujoco.mju_quat2Mat(cam_in_body, model.cam_quat[cid])
        link = mat_mul(cam_in_body, LINK_IN_CAMERA)
        optical = mat_t_mul(LINK_IN_CAMERA, OPTICAL_IN_CAMERA)  # the optical frame in camera_link
        self.static.append(transform(self.frame_of(body), cam.link,
                                     model.cam_pos[cid], quat_of(link)))
        for frame in (cam.color_optical, cam.depth_optical):
            self.static.append(transform(cam.link, frame, (0.0, 0.0, 0.0),
                                         quat_of(optical)))
