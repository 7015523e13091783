"""The physics node's swarm mode: one MuJoCo world with every robot of a robots: section.

One node steps the whole world (robots collide with each other, and the step is one
``mj_step`` for all of them), publishing each robot's topics under its namespace:
``/ROBOT/odom``, ``/ROBOT/joint_states``, ``/ROBOT/imu`` and, taking ``/ROBOT/cmd_vel`` and
``/ROBOT/joint_commands``; ``/tf`` carries every robot's moving frames (``map ->
ROBOT/odom -> ROBOT/base_link -> ...``), ``/tf_static`` their fixed ones, once, and
``/cosim/world_state`` the whole world's state for the sensor nodes' mirrors.

Collisions are counted apart: a robot touching an obstacle, and two robots touching each
other (one event for the pair). Each robot's goal is checked in ground truth; the
``swarm_goal`` metric is 1 once enough robots (``success_fraction``) have reached theirs.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np
from tf2_msgs.msg import TFMessage

from descriptions.world_geometry import floor_mask
from nodes.contract import Tick
from nodes.physics import messages as m
from nodes.physics.drive import DiffDrive
from nodes.physics.frames import CameraFrames, RobotFrames
from nodes.physics.imu import SimulatedImu
from nodes.physics.world import named_id, wheel_geometry
from plan.robots import RobotsLayout, namespaced, prefixed

JOINT = mujoco.mjtObj.mjOBJ_JOINT
ACTUATOR = mujoco.mjtObj.mjOBJ_ACTUATOR
BODY = mujoco.mjtObj.mjOBJ_BODY


def robot_params(params, robot: str):
    """The physics parameters with every name of the description as robot ``robot``'s
    copy has it in the swarm world (``robot_3/base_link``), frames likewise."""
    p = lambda name: prefixed(robot, name)  # noqa: E731 - one short rename, used a lot
    tf = params.tf
    if tf is not None:
        tf = tf.model_copy(update={
            "sites": {p(site): p(frame) for site, frame in tf.sites.items()},
            "cameras": [CameraFrames(camera=p(c.camera), link_frame=p(c.link_frame),
                                     color_optical_frame=p(c.color_optical_frame),
                                     depth_optical_frame=p(c.depth_optical_frame))
                        for c in tf.cameras]})
    imu = params.imu
    if imu is not None:
        imu = imu.model_copy(update={key: p(getattr(imu, key)) for key in
                                     ("site", "frame_id", "gyro", "accelerometer",
                                      "orientation")})
    return params.model_copy(update={
        "base_body": p(params.base_body), "odom_frame": p(params.odom_frame),
        "base_frame": p(params.base_frame), "wheel_joints": tuple(map(p, params.wheel_joints)),
        "wheel_actuators": tuple(map(p, params.wheel_actuators)),
        "position_joints": tuple(map(p, params.position_joints)),
        "position_actuators": tuple(map(p, params.position_actuators)),
        "tf": tf, "imu": imu, "start": None, "robots": []})


def swarm_outputs(params) -> dict[str, type]:
    """Every robot's namespaced outputs, the shared /tf and the world state."""
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import Imu, JointState
    from std_msgs.msg import Float64MultiArray

    out: dict[str, type] = {"/cosim/world_state": Float64MultiArray}
    for robot in params.robots:
        out[namespaced(robot, "/odom")] = Odometry
        out[namespaced(robot, "/joint_states")] = JointState
        if params.imu is not None:
            out[namespaced(robot, "/imu")] = Imu
    if params.tf is not None:
        out["/tf"] = TFMessage
    return out


class Rig:
    """One robot of the world: its joints, actuators, drive, frames, IMU and goal."""

    def __init__(self, model: mujoco.MjModel, params, rng: np.random.Generator,
                 goal: dict[str, float]):
        self.params = params
        base = named_id(model, BODY, params.base_body)
        free = model.body_jntadr[base]
        self.qadr = int(model.jnt_qposadr[free])
        self.vadr = int(model.jnt_dofadr[free])
        self.root = int(model.body_rootid[base])
        radius, separation = wheel_geometry(model, *params.wheel_joints)
        self.drive = DiffDrive(radius, separation, params.max_linear_speed,
                               params.max_angular_speed, params.max_linear_accel,
                               params.max_angular_accel)
        self.wheel_act = [named_id(model, ACTUATOR, a) for a in params.wheel_actuators]
        self.head_act = [named_id(model, ACTUATOR, a) for a in params.position_actuators]
        self.joint_names = list(params.wheel_joints) + list(params.position_joints)
        joints = [named_id(model, JOINT, j) for j in self.joint_names]
        self.joint_q = model.jnt_qposadr[joints]
        self.joint_v = model.jnt_dofadr[joints]
        self.imu = SimulatedImu(model, params.imu, rng) if params.imu else None
        self.frames = None
        if params.tf is not None:
            imu_site = {params.imu.site: params.imu.frame_id} if params.imu else {}
            self.frames = RobotFrames(model, params.tf, params.base_body, params.base_frame,
                                      params.odom_frame, imu_site, params.position_joints)
        self.goal = goal
        self.goal_time_ns: int | None = None
        self.path_length = 0.0
        self.last_xy: tuple[float, float] | None = None
        self.hits_obstacles = 0
        self.hits_robots = 0


class SwarmContacts:
    """Collision events: a new contact between a robot and an obstacle (counted for the
    robot) or between two robots (counted once for the pair, and for each robot). The
    floor and a robot's own parts do not count."""

    def __init__(self, model: mujoco.MjModel, rigs: list[Rig]):
        root_of = {rig.root: i for i, rig in enumerate(rigs)}
        roots = model.body_rootid[model.geom_bodyid]
        self.owner = np.array([root_of.get(int(r), -1) for r in roots], dtype=np.int64)
        self.floor = floor_mask(model)
        self.rigs = rigs
        self.touching: frozenset[tuple[int, int]] = frozenset()
        self.obstacle_events = 0
        self.robot_events = 0
        self._last = b""

    def update(self, data: mujoco.MjData) -> None:
        """Count the pairs touching now that were not one substep ago."""
        n = data.ncon
        geoms = data.contact.geom[:n]
        key = geoms.tobytes()
        if key == self._last:
            return
        self._last = key
        if n == 0:
            self.touching = frozenset()
            return
        a, b = geoms[:, 0], geoms[:, 1]
        oa, ob = self.owner[a], self.owner[b]
        keep = ~self.floor[a] & ~self.floor[b] & (oa != ob)
        now = frozenset((int(x), int(y)) if x < y else (int(y), int(x))
                        for x, y in geoms[keep].tolist())
        for x, y in now - self.touching:
            ox, oy = int(self.owner[x]), int(self.owner[y])
            if ox >= 0 and oy >= 0:
                self.robot_events += 1
                self.rigs[ox].hits_robots += 1
                self.rigs[oy].hits_robots += 1
            else:
                self.obstacle_events += 1
                self.rigs[max(ox, oy)].hits_obstacles += 1
        self.touching = now


class SwarmPhysics:
    """Steps the one world with every robot; what PhysicsNode does for one, for all."""

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, params, layout: RobotsLayout,
                 rng: np.random.Generator, substeps: int, dt: float):
        self.model, self.data, self.params = model, data, params
        self.substeps, self.dt = substeps, dt
        self.rigs = [Rig(model, robot_params(params, r), rng, layout.goal_of(r))
                     for r in params.robots]
        self.names = list(params.robots)
        self.needed = layout.needed
        self.contacts = SwarmContacts(model, self.rigs)
        mujoco.mj_forward(model, data)
        self.contacts.update(data)
        self.contacts.obstacle_events = self.contacts.robot_events = 0
        for rig in self.rigs:
            rig.hits_obstacles = rig.hits_robots = 0
        self.cmd_topics = [namespaced(r, "/cmd_vel") for r in self.names]
        self.head_topics = [namespaced(r, "/joint_commands") for r in self.names]
        self.started = False
        self.needs_kinematics = any(r.frames is not None and r.frames.needs_kinematics
                                    for r in self.rigs)

    def step(self, tick: Tick, inputs: dict[str, Any]) -> dict[str, Any]:
        """Integrate one period for every robot (except at the first activation), publish."""
        ctrl = self.data.ctrl
        for rig, topic in zip(self.rigs, self.head_topics, strict=True):
            msg = inputs.get(topic)
            if msg is not None:
                if len(msg.data) != len(rig.head_act):
                    raise ValueError(f"{topic} must carry {len(rig.head_act)} positions, "
                                     f"got {len(msg.data)}")
                ctrl[rig.head_act] = np.asarray(msg.data, dtype=np.float64)
        first = not self.started
        if self.started:
            commands = [m.twist_of(inputs.get(t)) for t in self.cmd_topics]
            for _ in range(self.substeps):
                for rig, (v, w) in zip(self.rigs, commands, strict=True):
                    left, right = rig.wheel_act
                    ctrl[left], ctrl[right] = rig.drive.update(v, w, self.dt)
                mujoco.mj_step(self.model, self.data)
                self.contacts.update(self.data)
            if any(rig.imu is not None for rig in self.rigs):
                mujoco.mj_forward(self.model, self.data)
            elif self.needs_kinematics:
                mujoco.mj_kinematics(self.model, self.data)
        self.started = True
        self._account(tick)
        out = self._publish()
        if first and self.params.tf is not None:
            out["/tf_static"] = TFMessage(transforms=[t for rig in self.rigs
                                                      for t in rig.frames.static])
        return out

    def _account(self, tick: Tick) -> None:
        qpos = self.data.qpos
        for rig in self.rigs:
            q = qpos[rig.qadr:rig.qadr + 7]
            x, y = float(q[0]), float(q[1])
            if rig.last_xy is not None:
                rig.path_length += float(np.hypot(x - rig.last_xy[0], y - rig.last_xy[1]))
            rig.last_xy = (x, y)
            if rig.goal_time_ns is None:
                g = rig.goal
                yaw_error = (m.yaw_of(q[3:7]) - g["yaw"] + np.pi) % (2 * np.pi) - np.pi
                if (np.hypot(x - g["x"], y - g["y"]) <= g["position_tolerance"]
                        and abs(yaw_error) <= g["yaw_tolerance"]):
                    rig.goal_time_ns = tick.time_ns

    def _publish(self) -> dict[str, Any]:
        d = self.data
        out: dict[str, Any] = {"/cosim/world_state": m.world_state(d.qpos, d.qvel)}
        transforms = []
        for rig, robot in zip(self.rigs, self.names, strict=True):
            p = rig.params
            base_q = d.qpos[rig.qadr:rig.qadr + 7]
            base_v = d.qvel[rig.vadr:rig.vadr + 6]
            out[namespaced(robot, "/odom")] = m.odometry(base_q, base_v, p.odom_frame,
                                                         p.base_frame)
            out[namespaced(robot, "/joint_states")] = m.joint_state(
                rig.joint_names, d.qpos[rig.joint_q], d.qvel[rig.joint_v],
                d.qfrc_actuator[rig.joint_v])
            if rig.imu is not None:
                out[namespaced(robot, "/imu")] = rig.imu.measure(d)
            if rig.frames is not None:
                transforms += rig.frames.dynamic(d, base_q)
        if self.params.tf is not None:
            out["/tf"] = TFMessage(transforms=transforms)
        return out

    def metrics(self) -> dict[str, float]:
        """Per robot (ROBOT/...): arrived, time_to_goal (s), path_length (m), collisions
        with obstacles and with robots, x, y; the swarm's totals; ``swarm_goal``."""
        out: dict[str, float] = {}
        arrived = 0
        for rig, robot in zip(self.rigs, self.names, strict=True):
            q = self.data.qpos[rig.qadr:rig.qadr + 7]
            done = rig.goal_time_ns is not None
            arrived += done
            out[f"{robot}/arrived"] = float(done)
            if done:
                out[f"{robot}/time_to_goal"] = rig.goal_time_ns / 1e9
            out[f"{robot}/path_length"] = rig.path_length
            out[f"{robot}/collisions_obstacles"] = float(rig.hits_obstacles)
            out[f"{robot}/collisions_robots"] = float(rig.hits_robots)
            out[f"{robot}/x"], out[f"{robot}/y"] = float(q[0]), float(q[1])
        c = self.contacts
        out.update({"robots": float(len(self.rigs)), "robots_arrived": float(arrived),
                    "collisions_obstacles": float(c.obstacle_events),
                    "collisions_robots": float(c.robot_events),
                    "collisions": float(c.obstacle_events + c.robot_events),
                    "path_length": sum(r.path_length for r in self.rigs),
                    "swarm_goal": float(arrived >= self.needed)})
        out["arrived"] = out["swarm_goal"]
        return out
