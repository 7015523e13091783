"""What robot_state_publisher and joint_state_broadcaster would publish for a described
robot (one a reader of descriptions.readers made, any format: only its robot model is read),
read from the MuJoCo state: a transform per URDF joint (parent link -> child link,
fixed joints once for /tf_static, moving ones per tick for /tf), ``odom -> root link`` for a
mobile robot, and the joint states of every movable joint. Frame names are the model's link
names (``robot_3/base_scan`` in a swarm, as ``frame_prefix`` gives them; ``base_scan`` for a
robot at the root); joint names in joint states are the description's own (the topic is
namespaced instead)."""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from descriptions.robot_model import RobotModel

BODY = mujoco.mjtObj.mjOBJ_BODY
JOINT = mujoco.mjtObj.mjOBJ_JOINT
SITE = mujoco.mjtObj.mjOBJ_SITE


@dataclass(frozen=True)
class LinkTransform:
    """One transform: parent and child frame, translation and quaternion (w, x, y, z)."""

    parent: str
    child: str
    pos: tuple[float, float, float]
    quat: tuple[float, float, float, float]


@dataclass(frozen=True)
class JointStates:
    """The movable joints' names (the description's), positions, velocities and efforts."""

    names: tuple[str, ...]
    position: tuple[float, ...]
    velocity: tuple[float, ...]
    effort: tuple[float, ...]


def _frame(model: mujoco.MjModel, link) -> tuple[bool, int] | None:
    """Where a link's frame is read: (True, site id) for a link whose site is on the world
    body (the link ``world`` of a fixed arm: a site where the robot is placed), else (False,
    body id); None when the world has neither."""
    sid = -1 if link.site is None else mujoco.mj_name2id(model, SITE, link.site)
    if sid >= 0 and int(model.site_bodyid[sid]) == 0:
        return True, sid
    bid = mujoco.mj_name2id(model, BODY, link.body)
    return (False, bid) if bid >= 0 else None


def _pose(data: mujoco.MjData, frame: tuple[bool, int]) -> tuple[np.ndarray, np.ndarray]:
    site, i = frame
    if site:
        return data.site_xpos[i], data.site_xmat[i].reshape(3, 3)
    return data.xpos[i], data.xmat[i].reshape(3, 3)


def _relative(data: mujoco.MjData, parent: tuple[bool, int], child: tuple[bool, int]
              ) -> tuple[tuple, tuple]:
    (pp, rp), (pc, rc) = _pose(data, parent), _pose(data, child)
    pos = rp.T @ (pc - pp)
    quat = np.empty(4)
    mujoco.mju_mat2Quat(quat, (rp.T @ rc).ravel())
    if quat[0] < 0:
        quat = -quat
    return tuple(float(v) for v in pos), tuple(float(v) for v in quat)


class RobotStateFrames:
    """The transforms and joint states of one robot (its model possibly scoped) in a
    compiled world: ids looked up once, values read per state."""

    def __init__(self, model: mujoco.MjModel, robot: RobotModel, odom_frame: str = "odom"):
        body = {k.name: _frame(model, k) for k in robot.links}
        missing = [name for name, bid in body.items() if bid is None]
        if missing:
            raise KeyError(f"links without a body in the world: {missing}")
        self.robot, self.odom_frame = robot, odom_frame
        self.root = body[robot.base_link][1]
        pairs = [(j, body[j.parent], body[j.child]) for j in robot.joints]
        self._fixed = [(j.parent, j.child, p, c) for j, p, c in pairs if j.kind == "fixed"]
        self._moving = [(j.parent, j.child, p, c) for j, p, c in pairs if j.kind != "fixed"]
        # the moving joints between two bodies (parent link, child link, parent body, child
        # body): their transforms come from the bodies' poses, every robot's together
        # (nodes.physics.batch); the others have an end on a site of the world body
        self.moving_bodies = [(pn, cn, p[1], c[1]) for pn, cn, p, c in self._moving
                              if not p[0] and not c[0]]
        self._moving_on_sites = [t for t in self._moving if t[2][0] or t[3][0]]
        self._joints = []
        for j in robot.joints:
            if j.kind in ("fixed", "floating", "planar"):
                continue
            jid = mujoco.mj_name2id(model, JOINT, j.name)
            if jid >= 0:
                self._joints.append((j.name[len(robot.prefix):], int(model.jnt_qposadr[jid]),
                                     int(model.jnt_dofadr[jid])))

    @property
    def joints(self) -> list[tuple[str, int, int]]:
        """Every movable joint as (its name in joint states, qpos address, dof address)."""
        return list(self._joints)

    def static(self, data: mujoco.MjData) -> list[LinkTransform]:
        """The fixed joints' transforms (for /tf_static, once)."""
        return [LinkTransform(pn, cn, *_relative(data, p, c)) for pn, cn, p, c in self._fixed]

    @property
    def has_moving(self) -> bool:
        """Whether any joint moves (its transform changes with the state)."""
        return bool(self._moving)

    def base(self, data: mujoco.MjData) -> LinkTransform | None:
        """``odom -> root link`` for a mobile robot (its free joint's pose), else None."""
        if not self.robot.mobile:
            return None
        quat = np.asarray(data.xquat[self.root], dtype=float)
        return LinkTransform(self.robot.frame_prefix + self.odom_frame, self.robot.base_link,
                             tuple(float(v) for v in data.xpos[self.root]),
                             tuple(float(v) for v in (-quat if quat[0] < 0 else quat)))

    def moving(self, data: mujoco.MjData) -> list[LinkTransform]:
        """The moving joints' transforms (for /tf; after mj_kinematics)."""
        return [LinkTransform(pn, cn, *_relative(data, p, c)) for pn, cn, p, c in self._moving]

    @property
    def has_moving_on_sites(self) -> bool:
        """Whether a moving joint has an end on a site (a fixed arm's ``world`` link on a
        joint that moves): not among ``moving_bodies``."""
        return bool(self._moving_on_sites)

    def moving_on_sites(self, data: mujoco.MjData) -> list[LinkTransform]:
        """The transforms of the moving joints not among ``moving_bodies`` (after
        mj_kinematics)."""
        return [LinkTransform(pn, cn, *_relative(data, p, c))
                for pn, cn, p, c in self._moving_on_sites]

    def joint_states(self, data: mujoco.MjData) -> JointStates:
        """Every movable joint's position, velocity and actuator effort."""
        return JointStates(
            tuple(n for n, _, _ in self._joints),
            tuple(float(data.qpos[q]) for _, q, _ in self._joints),
            tuple(float(data.qvel[d]) for _, _, d in self._joints),
            tuple(float(data.qfrc_actuator[d]) for _, _, d in self._joints))
