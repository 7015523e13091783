"""The physics node's robots: one MuJoCo world with every robot of the scenario, each read
from the one robot model (``NodeConfig.robots``). A scenario without a robots: section is a
swarm of one unnamed robot, stepped by the same code, its topics and frames unprefixed.

One node steps the whole world (robots collide with each other, and the step is one
``mj_step`` for all of them), publishing each robot's topics under its namespace:
``/ROBOT/odom``, ``/ROBOT/joint_states``, ``/ROBOT/imu`` and, taking ``/ROBOT/cmd_vel`` and
``/ROBOT/joint_commands``; ``/tf`` carries every robot's moving frames (``map ->
ROBOT/odom -> ROBOT/base_link -> ...``), ``/tf_static`` their fixed ones, once, and
``/cosim/world_state`` the whole world's state for the sensor nodes' mirrors. A robot at the
root (a lone robot of a robots: section) has its topics and frames unprefixed (``/odom``,
``odom -> base_link``), its MuJoCo names still ``ROBOT/...`` (``RobotModel.namespace``).

Collisions are counted apart: a robot touching an obstacle, and two robots touching each
other (one event for the pair). Each robot's goal is checked in ground truth; the
``swarm_goal`` metric is 1 once enough robots (``success_fraction``) have reached theirs.
"""

from __future__ import annotations

from fractions import Fraction
from typing import Any

import mujoco
import numpy as np
from tf2_msgs.msg import TFMessage

from descriptions.readers import robot_description_text
from descriptions.robot_model import RobotModel
from descriptions.world_geometry import floor_mask
from nodes.contract import Tick, node_seed
from nodes.physics import messages as m
from nodes.physics.batch import IMU, SwarmBook, SwarmDrives
from nodes.physics.described_rig import (
    ROBOT_DESCRIPTION,
    DescribedRobot,
    rig_params,
    robot_description,
)
from nodes.physics.drive import DiffDrive
from nodes.physics.frames import CameraFrames, mjcf_frames
from nodes.physics.imu import SimulatedImu
from nodes.physics.world import named_id
from nodes.physics.world_events import LiveWorld, geom_map
from plan.events import parse_edits
from plan.interactive import SET_POSE_TOPIC, WORLD_EDITS_TOPIC
from plan.robots import frame_prefix, namespaced, prefixed
from plan.topic_names import CMD_VEL, JOINT_COMMANDS, JOINT_STATES, ODOM
from plan.twin import MIRROR_JOINTS_TOPIC, MIRROR_TOPIC

JOINT = mujoco.mjtObj.mjOBJ_JOINT
ACTUATOR = mujoco.mjtObj.mjOBJ_ACTUATOR
BODY = mujoco.mjtObj.mjOBJ_BODY


def robot_params(params, robot: str, namespace: str | None = None):
    """The physics parameters with every name of the description as robot ``robot``'s
    copy has it in the swarm world (``robot_3/base_link``), frames in its ROS
    ``namespace`` (default: its name; '' the root: ``base_link``); as they are for the
    unnamed robot. What the world check of a swarm's MJCF robot reads, before its model is
    read by these names (a rig takes them from the model: ``rig_params``)."""
    if not robot:
        return params
    p = lambda name: prefixed(robot, name)  # noqa: E731 - one short rename, used a lot
    fp = frame_prefix(robot if namespace is None else namespace)
    f = lambda frame: fp + frame  # noqa: E731 - its frames' rename
    tf = params.tf
    if tf is not None:
        tf = tf.model_copy(update={
            "sites": {p(site): f(frame) for site, frame in tf.sites.items()},
            "cameras": [CameraFrames(camera=p(c.camera), link_frame=f(c.link_frame),
                                     color_optical_frame=f(c.color_optical_frame),
                                     depth_optical_frame=f(c.depth_optical_frame))
                        for c in tf.cameras]})
    imu = params.imu
    if imu is not None:
        imu = imu.model_copy(update={key: (f if key == "frame_id" else p)(getattr(imu, key))
                                     for key in ("site", "frame_id", "gyro", "accelerometer",
                                                 "orientation")})
    return params.model_copy(update={
        "base_body": p(params.base_body), "odom_frame": f(params.odom_frame),
        "base_frame": f(params.base_frame),
        "wheel_joints": None if params.wheel_joints is None else tuple(map(p, params.wheel_joints)),
        "wheel_actuators": tuple(map(p, params.wheel_actuators)),
        "position_joints": tuple(map(p, params.position_joints)),
        "position_actuators": tuple(map(p, params.position_actuators)),
        "tf": tf, "imu": imu, "start": None})


def robot_rng(rng: np.random.Generator, robot: str) -> np.random.Generator:
    """The generator of a robot that enters a running world (its IMU's bias and noise):
    seeded by the node's seed (``rng``'s) and the robot's name, so its draws are the same
    whatever tick it enters at, and the draws of the robots already there are unchanged."""
    return np.random.default_rng(node_seed(rng.bit_generator.seed_seq.entropy, robot))


class Rig:
    """One robot of the world, as its model describes it: its base (free, or fixed to the
    world), drive, commanded joints, frames, IMU and goal."""

    def __init__(self, model: mujoco.MjModel, robot: RobotModel, params, rng: np.random.Generator,
                 goal: dict[str, float] | None, joint_goal: dict[str, Any] | None = None,
                 imu: SimulatedImu | None = None):
        """``rng`` draws its IMU's bias and noise; ``imu``: its IMU in the world before a
        recompile, whose bias and generator it keeps."""
        self.name = robot.name
        self.described = None  # a described robot's joint states and links (its model's)
        if robot.described:
            self.described = DescribedRobot(model, robot, params.odom_frame)
        self.params = params = rig_params(params, robot)
        self.base = named_id(model, BODY, robot.base)
        free = model.body_jntadr[self.base]
        self.mobile = free >= 0 and model.jnt_type[free] == mujoco.mjtJoint.mjJNT_FREE
        self.qadr = int(model.jnt_qposadr[free]) if self.mobile else None
        self.vadr = int(model.jnt_dofadr[free]) if self.mobile else None
        self.root = int(model.body_rootid[self.base])
        self.drive = None
        wheels: list[str] = []
        if robot.drive is not None:
            d = robot.drive
            if not self.mobile:
                raise ValueError(f"body {robot.base!r} has no free joint")
            self.drive = DiffDrive(d.wheel_radius, d.wheel_separation, params.max_linear_speed,
                                   params.max_angular_speed, params.max_linear_accel,
                                   params.max_angular_accel)
            self.wheel_act = [named_id(model, ACTUATOR, a)
                              for a in (d.left_actuator, d.right_actuator)]
            wheels = [d.left_joint, d.right_joint]
        self.head_act = [named_id(model, ACTUATOR, a.actuator) for a in robot.actuated]
        self.position_joints = [a.joint for a in robot.actuated]
        self.joint_names = wheels + self.position_joints
        joints = [named_id(model, JOINT, j) for j in self.joint_names]
        self.joint_q = model.jnt_qposadr[joints]
        self.joint_v = model.jnt_dofadr[joints]
        # what /joint_states carries: the commanded joints, or a described robot's movable ones
        self.state_names, self.state_q, self.state_v = (
            ([robot.frame(j) for j in self.joint_names], self.joint_q, self.joint_v)
            if self.described is None else self.described.state_joints)
        self.odom_frame = params.odom_frame
        self.base_frame = robot.base_link
        self.topics = {t: namespaced(robot.namespace, t) for t in
                       (CMD_VEL, JOINT_COMMANDS, MIRROR_TOPIC, MIRROR_JOINTS_TOPIC, ODOM,
                        JOINT_STATES, IMU, ROBOT_DESCRIPTION)}
        self.imu = None
        if params.imu:
            self.imu = (SimulatedImu(model, params.imu, rng) if imu is None
                        else SimulatedImu(model, params.imu, imu.rng, imu.bias))
        self.frames = None  # nodes.physics.frames.RobotFrames, whatever describes the robot
        if params.tf is not None and self.described is not None:
            self.frames = self.described.frames(params.tf)
        elif params.tf is not None:
            imu_site = {params.imu.site: params.imu.frame_id} if params.imu else {}
            self.frames = mjcf_frames(model, params.tf, robot, self.odom_frame, imu_site)
        self.goal = goal
        goal_joints = [] if joint_goal is None else [named_id(model, JOINT, j)
                                                     for j in joint_goal["positions"]]
        self.joint_goal = joint_goal
        self.goal_q = model.jnt_qposadr[goal_joints]
        self.goal_v = model.jnt_dofadr[goal_joints]
        self.goal_time_ns: int | None = None
        self.hits_obstacles = 0
        self.hits_robots = 0
        self.refused_command = None  # the last wrong-length /joint_commands noted
        self.teleported = None  # the last /cosim/set_pose applied

    def place(self, data: mujoco.MjData, x: float, y: float, yaw: float) -> None:
        """Put the base at (x, y) facing ``yaw`` (z, roll and pitch stay on the floor)."""
        base = data.qpos[self.qadr:self.qadr + 7]
        base[:2] = x, y
        base[3:] = np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)

    def base_pose(self, data: mujoco.MjData) -> np.ndarray:
        """The base's (x, y, z, qw, qx, qy, qz): its free joint, or its fixed world pose."""
        if self.mobile:
            return data.qpos[self.qadr:self.qadr + 7]
        return np.concatenate([data.xpos[self.base], data.xquat[self.base]])

    def position_command(self, data: mujoco.MjData, msg, note) -> None:
        """Set the position servos' targets; a command of the wrong length is refused with a
        note (once for each new such command: the input repeats at every activation)."""
        if msg is None:
            return
        if len(msg.data) != len(self.head_act):
            if msg != self.refused_command:
                self.refused_command = msg
                note(f"{self.topics[JOINT_COMMANDS]} refused: it carries {len(msg.data)} "
                     f"positions, this robot takes {len(self.head_act)} "
                     f"{self.position_joints}; the joints keep their targets")
            return
        data.ctrl[self.head_act] = np.asarray(msg.data, dtype=np.float64)

    def mirror(self, data: mujoco.MjData, odom, joints) -> None:
        """Place the base at the real robot's planar pose with its velocities (z, roll and
        pitch stay on the floor), and the joints /real/joint_states names."""
        p, q = odom.pose.pose.position, odom.pose.pose.orientation
        yaw = m.yaw_of(np.array([q.w, q.x, q.y, q.z]))
        self.place(data, p.x, p.y, yaw)
        v, w = odom.twist.twist.linear, odom.twist.twist.angular  # in the base frame
        vel = data.qvel[self.vadr:self.vadr + 6]
        vel[:] = (v.x * np.cos(yaw) - v.y * np.sin(yaw), v.x * np.sin(yaw) + v.y * np.cos(yaw),
                  0.0, 0.0, 0.0, w.z)
        self.drive.v, self.drive.w = v.x, w.z
        if joints is not None:
            index = {name: i for i, name in enumerate(self.joint_names)}
            for j, name in enumerate(joints.name):
                i = index.get(name)
                if i is None:
                    continue
                if j < len(joints.position):
                    data.qpos[self.joint_q[i]] = joints.position[j]
                if j < len(joints.velocity):
                    data.qvel[self.joint_v[i]] = joints.velocity[j]

    def teleport(self, model: mujoco.MjModel, data: mujoco.MjData, msg) -> None:
        """Put the base at rest at the request's x, y and yaw, so this tick publishes it. The
        external node publishes its latest message at every activation: each request (its
        description says which) applies once; in a swarm, to the robot it names."""
        if (msg is None or not msg.name or msg == self.teleported or not self.mobile
                or self.name not in ("", msg.name)):
            return
        self.teleported = msg
        p, q = msg.pose.position, msg.pose.orientation
        self.place(data, p.x, p.y, m.yaw_of(np.array([q.w, q.x, q.y, q.z])))
        data.qvel[:] = 0.0
        self.drive.v = self.drive.w = 0.0
        mujoco.mj_forward(model, data)

    def check_goal(self, data: mujoco.MjData, tick: Tick) -> None:
        """The goal in ground truth: the pose within the goal's tolerances, or the joints
        within the joint goal's of their positions and of rest (sticky). The path driven
        and the check of every robot at once: nodes.physics.batch.SwarmBook.account."""
        if self.goal_time_ns is not None:
            return
        g = self.joint_goal
        if g is not None:
            target = np.fromiter(g["positions"].values(), dtype=np.float64)
            if (np.all(np.abs(data.qpos[self.goal_q] - target) <= g["tolerance"])
                    and np.all(np.abs(data.qvel[self.goal_v]) <= g["speed_tolerance"])):
                self.goal_time_ns = tick.time_ns
            return
        g = self.goal
        if g is None or not self.mobile:
            return
        q = data.qpos[self.qadr:self.qadr + 7]
        x, y = float(q[0]), float(q[1])
        yaw_error = (m.yaw_of(q[3:7]) - g["yaw"] + np.pi) % (2 * np.pi) - np.pi
        if (np.hypot(x - g["x"], y - g["y"]) <= g["position_tolerance"]
                and abs(yaw_error) <= g["yaw_tolerance"]):
            self.goal_time_ns = tick.time_ns


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

    def rebind(self, model: mujoco.MjModel, moved: np.ndarray) -> None:
        """Follow a world recompiled with objects added or taken out (``moved``: each old
        geom's new id, -1 gone): every geom not a robot's is an obstacle's."""
        root_of = {rig.root: i for i, rig in enumerate(self.rigs)}
        roots = model.body_rootid[model.geom_bodyid]
        self.owner = np.array([root_of.get(int(r), -1) for r in roots], dtype=np.int64)
        self.floor = floor_mask(model)
        self.touching = frozenset((int(moved[a]), int(moved[b])) for a, b in self.touching
                                  if moved[a] >= 0 and moved[b] >= 0)
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
    """Steps the one world with every robot (one, unnamed, without a robots: section)."""

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, params, config,
                 rng: np.random.Generator, substeps: int, dt: float, note, live=None):
        self.model, self.data, self.params = model, data, params
        self.live = live  # nodes.physics.world_events.LiveWorld: the scenario's events
        self.world, self.layout = config.world, config.layout
        self._edits_text, self._edits = "", []  # the clients' edits (/cosim/world_edits)
        self.substeps, self.dt, self.note = substeps, dt, note
        layout = config.layout
        self.rng, self.all_robots = rng, tuple(config.robots)
        self.robot_models = {robot.name: robot for robot in self.all_robots}  # by name
        present = None if layout is None else (  # the robots in the world now
            live.robots if live is not None else set(layout.at_start.names))
        self.rigs = [Rig(model, robot, params, rng,
                         layout.goal_of(robot.name) if robot.name else config.goal,
                         None if robot.name else config.joint_goal)
                     for robot in config.robots if present is None or robot.name in present]
        self.names = [rig.name for rig in self.rigs]
        self.entered: list[Rig] = []  # the robots that entered at this tick
        self.rebound = False  # whether a robot entered or left (the rigs were made again)
        self._urdf_texts: dict[tuple, str] = {}  # each description's URDF, read once
        self.needed = layout.needed if layout is not None else 1
        self.goals = config.goal is not None or config.joint_goal is not None
        start = params.start
        for rig in self.rigs:
            if start is not None and not rig.name and rig.mobile:
                rig.place(data, start.x, start.y, start.yaw)
        self.contacts = SwarmContacts(model, self.rigs)
        mujoco.mj_forward(model, data)
        self.contacts.update(data)
        self.contacts.obstacle_events = self.contacts.robot_events = 0
        for rig in self.rigs:
            rig.hits_obstacles = rig.hits_robots = 0
        self.hosted = None  # the robots' controller managers, run in this step
        if params.controller_manager is not None:
            from nodes.ros2_control.hosted import HostedManagers

            self.hosted = HostedManagers(params.controller_manager, model, self.rigs,
                                         [self.robot_models[rig.name] for rig in self.rigs],
                                         config.held_inputs, note)
        self.period_ns = config.period_ns
        self.hosted_every, self.hosted_period_ns = 1, self.period_ns  # ticks, ns per update
        if self.hosted is not None:  # update_rate = this rate / n: every n-th activation
            from nodes.ros2_control.hosted import manager_period_ns

            self.hosted_period_ns = manager_period_ns(params.controller_manager, self.period_ns)
            self.hosted_every = int(Fraction(self.hosted_period_ns) / Fraction(config.tick_ns))
        self.joint_commands = self.hosted is None or not self.hosted.commands_joints
        self._bind()
        self.started = False

    def urdf_text(self, rig: Rig) -> str:
        """The robot's description as URDF (/robot_description), read once per file by the
        reader its model names."""
        robot = self.robot_models[rig.name]
        source = (robot.source, robot.settings)
        if source not in self._urdf_texts:
            self._urdf_texts[source] = robot_description_text(*source)
        return self._urdf_texts[source]

    def _bind(self) -> None:
        """The per-tick bookkeeping over the rigs (made again when a robot enters or
        leaves)."""
        # a base whose wheels a diff drive controller commands is driven by it, not here
        hosted_base = self.hosted is not None and self.hosted.drives_base
        self.driven = [rig for rig in self.rigs if rig.drive is not None and not hosted_base]
        self.drives = SwarmDrives(self.driven, self.dt)
        self.book = SwarmBook(self.model, self.rigs, frozenset() if self.hosted is None
                              else self.hosted.published)
        self.any_imu = any(rig.imu is not None for rig in self.rigs)
        self.needs_kinematics = any(r.frames is not None and r.frames.needs_kinematics
                                    for r in self.rigs)

    def _rebind_robots(self, moved: np.ndarray) -> None:
        """Make every rig again for the recompiled world with the robots in it now (the
        live world's), each one that was there keeping its drive, goal, collision counts and
        path and its IMU's bias and noise generator; a robot that entered starts at rest
        where its event put it, its IMU drawing from a generator of its own (``robot_rng``:
        the same whenever it enters, and the others' draws unchanged)."""
        old = {rig.name: rig for rig in self.rigs}
        paths = {rig.name: self.book.path_length(rig) for rig in self.rigs}
        last = self.book.last_xy
        slots = {rig.name: self.book.mobile_slot[id(rig)] for rig in self.rigs
                 if id(rig) in self.book.mobile_slot}
        rigs = []
        self.entered = []
        for robot in self.all_robots:
            if robot.name not in self.live.robots:
                continue
            prev = old.get(robot.name)
            rig = Rig(self.model, robot, self.params,
                      robot_rng(self.rng, robot.name) if prev is None else self.rng,
                      self.layout.goal_of(robot.name), None,
                      None if prev is None else prev.imu)
            if prev is None:
                self.entered.append(rig)
            else:
                for key in ("goal_time_ns", "hits_obstacles", "hits_robots",
                            "refused_command", "teleported"):
                    setattr(rig, key, getattr(prev, key))
                if prev.drive is not None:
                    rig.drive = prev.drive
            rigs.append(rig)
        contacts = self.contacts
        self.rigs, self.names = rigs, [rig.name for rig in rigs]
        self.contacts = SwarmContacts(self.model, rigs)
        self.contacts.obstacle_events = contacts.obstacle_events
        self.contacts.robot_events = contacts.robot_events
        self.contacts.touching = frozenset(
            (int(moved[a]), int(moved[b])) for a, b in contacts.touching
            if moved[a] >= 0 and moved[b] >= 0)
        if self.hosted is not None:  # before the book: it leaves the managers' topics to them
            self.hosted.rebind(self.model, rigs, [self.robot_models[rig.name] for rig in rigs])
        self._bind()
        book = self.book
        for rig in rigs:
            slot = book.mobile_slot.get(id(rig))
            if slot is not None and rig.name in paths:
                book.path[slot] = paths[rig.name]
        if last is not None and len(book.path):
            xy = self.data.qpos[book.qpos_index[:, :2]]
            x, y = xy[:, 0].copy(), xy[:, 1].copy()
            for rig in rigs:
                slot = book.mobile_slot.get(id(rig))
                if slot is not None and rig.name in slots:
                    x[slot], y[slot] = last[0][slots[rig.name]], last[1][slots[rig.name]]
            book.last_xy = (x, y)
        self.rebound = True

    def step(self, tick: Tick, inputs: dict[str, Any]) -> dict[str, Any]:
        """Integrate one period for every robot (except at the first activation; not while a
        twin's real robot places it), publish."""
        model, data = self.model, self.data
        for rig in self.rigs if self.joint_commands else ():
            rig.position_command(data, inputs.get(rig.topics[JOINT_COMMANDS]), self.note)
        first = not self.started
        mirrored = False
        for rig in self.rigs:
            real = inputs.get(rig.topics[MIRROR_TOPIC])
            if real is not None and real.header.frame_id:  # a twin: the real robot, as is
                rig.mirror(data, real, inputs.get(rig.topics[MIRROR_JOINTS_TOPIC]))
                mirrored = True
        if mirrored:
            mujoco.mj_forward(model, data)
            self.contacts.update(data)
        elif self.started:
            commands = [m.twist_of(inputs.get(rig.topics[CMD_VEL])) for rig in self.driven]
            self.drives.integrate(model, data, commands, self.substeps,
                                  lambda: self.contacts.update(data))
            # bring what mj_step leaves one substep behind (it computes sensors and body
            # poses before integrating) up to the state published; neither call changes
            # what the next mj_step computes
            if self.any_imu:
                mujoco.mj_forward(model, data)
            elif self.needs_kinematics:
                mujoco.mj_kinematics(model, data)
        self.started = True
        teleport = inputs.get(SET_POSE_TOPIC)
        if teleport is not None:
            for rig in self.rigs:
                rig.teleport(model, data, teleport)
        edits = inputs.get(WORLD_EDITS_TOPIC)
        if edits is not None and edits.data and self.live is None:
            self._go_live()
        if self.live is not None:
            self._apply_events(tick, edits)
        self.book.account(self.data, tick)
        out = self._publish()
        if self.hosted is not None and tick.index % self.hosted_every == 0:  # read, update,
            # write at the manager's update_rate: the commands act from now on
            self.hosted.step(tick.time_ns, self.hosted_period_ns, self.data, inputs, out)
        if (first or self.entered) and self.params.tf is not None:  # again with a robot in
            out["/tf_static"] = TFMessage(transforms=[t for rig in self.rigs
                                                      for t in rig.frames.static])
        if first and self.params.robot_description:
            for rig in self.rigs:
                out[rig.topics[ROBOT_DESCRIPTION]] = robot_description(self.urdf_text(rig))
        if self.entered:  # a robot that entered at this tick: its latched description,
            # and again those of the robots there from the start, latched outputs without a
            # window being due again when a robot enters (plan.scenario.NodePlan.windowed)
            if self.params.robot_description and not first:
                start = set(self.layout.at_start.names)
                for rig in self.rigs:
                    if rig in self.entered or rig.name in start:
                        out[rig.topics[ROBOT_DESCRIPTION]] = robot_description(
                            self.urdf_text(rig))
            self.entered = []
        return out

    def _hosted_metrics(self) -> dict[str, float]:
        return self.hosted.metrics() if self.hosted is not None else {}

    def _go_live(self) -> None:
        """A client's first edit of a world that had no events: from now on the world is
        kept as a spec to recompile, the state carried over."""
        live = LiveWorld(self.world, self.layout, (), self.note)
        self.data = live.take_over(self.model, self.data)
        self.model, self.live = live.model, live
        if self.params.threads > 1:
            mujoco.mju_threadpool(self.data, self.params.threads)

    def _apply_events(self, tick: Tick, edits=None) -> None:
        """Put in and take out the objects of the events due at this tick's time and of
        the clients' edits new at this tick (after integrating up to it, so the state
        published at the tick has them)."""
        if edits is not None and edits.data != self._edits_text:
            self._edits_text, self._edits = edits.data, parse_edits(edits.data)
        old = self.model
        changed = self.live.advance(self.data, tick.time_ns, self._edits)
        if changed is None:
            return
        self.model, self.data = changed
        if self.params.threads > 1:
            mujoco.mju_threadpool(self.data, self.params.threads)
        moved = geom_map(old, self.model)
        if self.layout is not None and (self.rebound or set(self.names) != self.live.robots):
            self._rebind_robots(moved)  # a robot entered or left: every index may move
        else:
            self.contacts.rebind(self.model, moved)

    def _publish(self) -> dict[str, Any]:
        d = self.data
        live = self.live
        state = (m.world_state(d.qpos, d.qvel) if live is None else
                 m.world_state(d.qpos, d.qvel, live.version, live.label))
        out: dict[str, Any] = {"/cosim/world_state": state}
        transforms = self.book.publish(d, out, self.params.tf is not None)
        if self.params.tf is not None:
            out["/tf"] = TFMessage(transforms=transforms)
        return out

    def metrics(self) -> dict[str, float]:
        """The unnamed robot: collisions, its ground-truth planar pose and whether it reached
        its goal. A swarm: per robot (ROBOT/...): arrived, time_to_goal (s), path_length (m),
        collisions with obstacles and with robots, x, y; the swarm's totals; ``swarm_goal``."""
        if self.names == [""]:
            rig = self.rigs[0]
            q = rig.base_pose(self.data)
            out = {"collisions": float(self.contacts.obstacle_events), "x": float(q[0]),
                   "y": float(q[1]), "yaw": m.yaw_of(q[3:7])}
            if self.goals:
                out["arrived"] = float(rig.goal_time_ns is not None)  # ground truth, sticky
            return {**out, **self._hosted_metrics()}
        out: dict[str, float] = {}
        arrived = 0
        for rig, robot in zip(self.rigs, self.names, strict=True):
            q = rig.base_pose(self.data)
            done = rig.goal_time_ns is not None
            arrived += done
            out[f"{robot}/arrived"] = float(done)
            if done:
                out[f"{robot}/time_to_goal"] = rig.goal_time_ns / 1e9
            out[f"{robot}/path_length"] = self.book.path_length(rig)
            out[f"{robot}/collisions_obstacles"] = float(rig.hits_obstacles)
            out[f"{robot}/collisions_robots"] = float(rig.hits_robots)
            out[f"{robot}/x"], out[f"{robot}/y"] = float(q[0]), float(q[1])
        c = self.contacts
        out.update(self._hosted_metrics())
        out.update({"robots": float(len(self.rigs)), "robots_arrived": float(arrived),
                    "collisions_obstacles": float(c.obstacle_events),
                    "collisions_robots": float(c.robot_events),
                    "collisions": float(c.obstacle_events + c.robot_events),
                    "path_length": sum(self.book.path_length(r) for r in self.rigs),
                    "swarm_goal": float(arrived >= self.needed)})
        out["arrived"] = out["swarm_goal"]
        return out
