"""The physics node: a MuJoCo world with a robot: a differential-drive base (or a base fixed
to the world, ``wheel_joints: null``: an arm on the floor) and position-servoed joints (the
pan-tilt head; the six joints of an arm).

Inputs: /cmd_vel (geometry_msgs/Twist, or TwistStamped with ``enable_stamped_cmd_vel``;
normally a delayed edge; absent means stop), /joint_commands (std_msgs/Float64MultiArray of
positions, one per ``position_joints`` entry in that order, optional; a command of another
length is refused with a note and the servos keep their targets) and /cosim/set_pose
(simulation_interfaces/NamedPose, optional: SetEntityState from an interactive run's clients;
a mobile base is put at rest at the pose's x, y and yaw) and /real/odom (nav_msgs/Odometry,
optional: a digital twin's real robot; once one has arrived the base is a kinematic mirror,
placed at its x, y and yaw with its velocities every activation instead of being driven, so
sensors render from the real robot's pose and contacts are those the real pose would have),
with /real/joint_states (sensor_msgs/JointState, optional) setting the named joints' positions
too.
Outputs at tick k are the state at time t_k: tick 0 publishes the initial state, every later
activation integrates one node period (a whole number of world timesteps) and publishes:
/odom, /joint_states, /cosim/world_state, /tf (nodes.physics.frames) and /imu
(nodes.physics.imu); /tf_static once, at the first activation, latched.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np
from geometry_msgs.msg import Twist, TwistStamped
from nav_msgs.msg import Odometry
from pydantic import BaseModel, ConfigDict, Field
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Float64MultiArray
from tf2_msgs.msg import TFMessage

from descriptions.world_geometry import floor_mask
from nodes.contract import StepNode, Tick
from nodes.physics import messages as m
from nodes.physics.contacts import CollisionCounter
from nodes.physics.drive import DiffDrive
from nodes.physics.frames import RobotFrames, TfParams, frame_problems, on_robot
from nodes.physics.imu import ImuParams, SimulatedImu, imu_problems
from nodes.physics.swarm import SwarmPhysics, robot_params, swarm_outputs
from nodes.physics.world import (
    NS_PER_S,
    load_model,
    named_id,
    robot_geoms,
    substeps,
    timestep_ns,
    wheel_geometry,
)
from plan.interactive import SET_POSE_TOPIC
from plan.robots import namespaced
from plan.topic_names import CMD_VEL, JOINT_COMMANDS, JOINT_STATES, ODOM
from plan.twin import MIRROR_JOINTS_TOPIC, MIRROR_TOPIC

JOINT = mujoco.mjtObj.mjOBJ_JOINT
ACTUATOR = mujoco.mjtObj.mjOBJ_ACTUATOR


class Pose2D(BaseModel):
    """A planar pose: position in metres, heading in radians."""

    model_config = ConfigDict(extra="forbid")
    x: float
    y: float
    yaw: float = 0.0


class PhysicsParams(BaseModel):
    """Robot names in the MJCF, the start pose, the drive limits, TF frames and the IMU."""

    model_config = ConfigDict(extra="forbid")
    start: Pose2D | None = Field(None, description="where the robot starts; default: as in MJCF")
    base_body: str = "base_link"
    odom_frame: str = "odom"
    base_frame: str = "base_link"
    wheel_joints: tuple[str, str] | None = Field(
        ("left_wheel_joint", "right_wheel_joint"),
        description="the drive's wheels; null: no drive (a base fixed to the world, an arm)")
    wheel_actuators: tuple[str, str] = ("left_wheel_motor", "right_wheel_motor")
    position_joints: list[str] = Field(
        ["pan_joint", "tilt_joint"], description="the joints /joint_commands positions, in order")
    position_actuators: list[str] = Field(
        ["pan_servo", "tilt_servo"], description="their position actuators, in the same order")
    max_linear_speed: float = Field(1.0, gt=0, description="m/s")
    max_angular_speed: float = Field(2.5, gt=0, description="rad/s")
    max_linear_accel: float = Field(2.0, gt=0, description="m/s^2")
    max_angular_accel: float = Field(6.0, gt=0, description="rad/s^2")
    enable_stamped_cmd_vel: bool = Field(False, description="take /cmd_vel as TwistStamped")
    tf: TfParams | None = Field(TfParams(), description="/tf and /tf_static; null: none")
    imu: ImuParams | None = Field(ImuParams(), description="/imu; null: none")
    robots: list[str] = Field([], description="set from the scenario's robots: section: "
                              "every robot's name; the node then steps them all, each under "
                              "its namespace (nodes.physics.swarm)")


class PhysicsNode(StepNode):
    """MuJoCo stepping, diff-drive and joint position control, odometry, collision counting."""

    Params = PhysicsParams
    needs_world = True
    type_keys = {CMD_VEL: "params.enable_stamped_cmd_vel"}

    @classmethod
    def outputs(cls, params: PhysicsParams) -> dict[str, type]:
        """Odometry, joint states, the world state that sensor nodes mirror, /tf and /imu."""
        if params.robots:
            return swarm_outputs(params)
        out = {ODOM: Odometry, JOINT_STATES: JointState,
               "/cosim/world_state": Float64MultiArray}
        if params.tf is not None:
            out["/tf"] = TFMessage
        if params.imu is not None:
            out["/imu"] = Imu
        return out

    @classmethod
    def latched_outputs(cls, params: PhysicsParams) -> dict[str, type]:
        """/tf_static: the robot's fixed frames, once."""
        return {"/tf_static": TFMessage} if params.tf is not None else {}

    @classmethod
    def input_types(cls, params: PhysicsParams) -> dict[str, type]:
        """/cmd_vel as Twist, or TwistStamped with ``enable_stamped_cmd_vel``."""
        twist = TwistStamped if params.enable_stamped_cmd_vel else Twist
        if params.robots:
            return {namespaced(r, CMD_VEL): twist for r in params.robots}
        return {CMD_VEL: twist, MIRROR_TOPIC: Odometry, MIRROR_JOINTS_TOPIC: JointState}

    @classmethod
    def world_problems(cls, params: PhysicsParams, model, goal) -> list[tuple[str, str, str]]:
        """The robot's bodies and joints exist; the start pose is inside the world, clear of
        every obstacle by the robot's footprint radius."""
        from descriptions.world_geometry import robot_footprint_radius, static_obstacles
        from plan.obstacles import place_problem

        if params.robots:  # each robot is checked as the first one is, its copy's names
            return cls.world_problems(robot_params(params, params.robots[0]), model, goal)
        body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, params.base_body)
        if body < 0:
            bodies = [model.body(j).name for j in range(1, model.nbody)]
            return [("params.base_body", f"the world has no body {params.base_body!r} (the "
                     f"robot this node drives); its bodies: {', '.join(bodies) or 'none'}.",
                     "the name of the robot's base body in the world, or a world that "
                     "includes the robot (e.g. <include file=\"robot.xml\"/>).")]
        free = model.body_jntadr[body]
        mobile = free >= 0 and model.jnt_type[free] == mujoco.mjtJoint.mjJNT_FREE
        if params.wheel_joints is not None and not mobile:
            return [("params.base_body", f"body {params.base_body!r} has no free joint.",
                     "a base body with <freejoint/>, or wheel_joints: null for a base fixed "
                     "to the world.")]
        joints = [model.joint(j).name for j in range(model.njnt)]
        for key, names in (("wheel_joints", params.wheel_joints or ()),
                           ("position_joints", params.position_joints)):
            missing = [n for n in names if n not in joints]
            if missing:
                return [(f"params.{key}", f"the world has no joint {missing[0]!r}; its "
                         f"joints: {', '.join(j for j in joints if j) or 'none'}.",
                         "joint names of the robot in the world.")]
        base_id = body
        for name in params.position_joints:
            jid = mujoco.mj_name2id(model, JOINT, name)
            if not on_robot(model, int(model.jnt_bodyid[jid]), base_id):
                return [("params.position_joints", f"joint {name!r} is not on the robot's "
                         "body tree.", f"joints of bodies under {params.base_body!r}.")]
        if len(params.position_actuators) != len(params.position_joints):
            return [("params.position_actuators", f"{len(params.position_actuators)} "
                     f"actuators for {len(params.position_joints)} position_joints.",
                     "one position actuator per position joint, in the same order.")]
        actuators = [model.actuator(a).name for a in range(model.nu)]
        missing = [a for a in params.position_actuators if a not in actuators]
        if missing:
            return [("params.position_actuators", f"the world has no actuator {missing[0]!r}; "
                     f"its actuators: {', '.join(a for a in actuators if a) or 'none'}.",
                     "actuator names of the robot in the world.")]
        if not mobile and params.start is not None:
            return [("params.start", f"body {params.base_body!r} is fixed to the world.",
                     "no start (the base stays where the world puts it).")]
        if params.imu is not None and (problems := imu_problems(model, params.imu)):
            return problems
        if params.tf is not None:
            imu_site = {params.imu.site: params.imu.frame_id} if params.imu else {}
            if problems := frame_problems(model, params.tf, params.base_body, imu_site):
                return problems
        if params.start is not None:
            radius = robot_footprint_radius(model, params.base_body)
            problem = place_problem(static_obstacles(model), params.start.x, params.start.y,
                                    radius)
            if problem:
                return [("params.start", f"the start {problem}.",
                         "a start pose inside the world with the robot clear of obstacles.")]
        return []

    @classmethod
    def period_problems(cls, params: PhysicsParams, model, period_ns: int
                        ) -> list[tuple[str, str, str]]:
        """The period must be a whole number of the world's timesteps (the substeps)."""
        try:
            step = timestep_ns(model, "")
        except ValueError:
            return []  # the world's own problem, reported when it loads
        if period_ns % step == 0:
            return []
        fits = [NS_PER_S // (k * step) for k in range(1, 1000)
                if NS_PER_S % (k * step) == 0][:5]
        example = f", e.g. {', '.join(map(str, fits))} Hz" if fits else ""
        return [("rate", f"the period {period_ns} ns is not a whole number of the world's "
                 f"timesteps ({step} ns, <option timestep={model.opt.timestep!r}>): physics "
                 "integrates whole timesteps in each period.",
                 f"a rate whose period is a multiple of {step} ns{example}; or change "
                 "<option timestep> in the world.")]

    @classmethod
    def accepted_inputs(cls, params: PhysicsParams) -> set[str]:
        """Joint position commands; with a drive, velocity commands, teleports and a real
        robot's pose (a twin) too; in a swarm, each robot's velocity and joint commands."""
        if params.robots:
            return {namespaced(r, t) for r in params.robots for t in (CMD_VEL, JOINT_COMMANDS)}
        mobile = ({CMD_VEL, SET_POSE_TOPIC, MIRROR_TOPIC, MIRROR_JOINTS_TOPIC}
                  if params.wheel_joints is not None else set())
        return mobile | {JOINT_COMMANDS}

    def setup(self) -> None:
        """Load the world, check the timestep against the period and place the robot."""
        p = self.params
        world = self.config.world
        self.model = load_model(world, self.config.robots)
        self.data = mujoco.MjData(self.model)
        self.substeps = substeps(self.model, world, self.config.period_ns)
        self.dt = timestep_ns(self.model, world) / 1e9
        self.swarm = None
        if p.robots:
            self.swarm = SwarmPhysics(self.model, self.data, p, self.config.robots, self.rng,
                                      self.substeps, self.dt)
            return
        self.base = named_id(self.model, mujoco.mjtObj.mjOBJ_BODY, p.base_body)
        free = self.model.body_jntadr[self.base]
        self.mobile = free >= 0 and self.model.jnt_type[free] == mujoco.mjtJoint.mjJNT_FREE
        if p.wheel_joints is not None and not self.mobile:
            raise ValueError(f"body {p.base_body!r} of world {world} has no free joint")
        self.qadr = int(self.model.jnt_qposadr[free]) if self.mobile else None
        self.vadr = int(self.model.jnt_dofadr[free]) if self.mobile else None
        if p.start is not None:
            q = self.data.qpos
            q[self.qadr:self.qadr + 2] = p.start.x, p.start.y
            q[self.qadr + 3:self.qadr + 7] = np.cos(p.start.yaw / 2), 0, 0, np.sin(p.start.yaw / 2)
        self.drive = None
        if p.wheel_joints is not None:
            radius, separation = wheel_geometry(self.model, *p.wheel_joints)
            self.drive = DiffDrive(radius, separation, p.max_linear_speed, p.max_angular_speed,
                                   p.max_linear_accel, p.max_angular_accel)
            self.wheel_act = [named_id(self.model, ACTUATOR, a) for a in p.wheel_actuators]
        self.position_act = [named_id(self.model, ACTUATOR, a) for a in p.position_actuators]
        self.refused_command = None  # the last wrong-length /joint_commands noted
        self.joint_names = list(p.wheel_joints or ()) + list(p.position_joints)
        joints = [named_id(self.model, JOINT, j) for j in self.joint_names]
        self.joint_q = self.model.jnt_qposadr[joints]
        self.joint_v = self.model.jnt_dofadr[joints]
        goal = self.config.joint_goal
        goal_joints = [] if goal is None else [named_id(self.model, JOINT, j)
                                               for j in goal["positions"]]
        self.goal_q = self.model.jnt_qposadr[goal_joints]
        self.goal_v = self.model.jnt_dofadr[goal_joints]
        self.collisions = CollisionCounter(robot_geoms(self.model, p.base_body),
                                           floor_mask(self.model))
        mujoco.mj_forward(self.model, self.data)
        self.collisions.update(self.data)
        self.collisions.events = 0  # touching at the start is not an event
        self.imu = SimulatedImu(self.model, p.imu, self.rng) if p.imu else None
        self.frames = None
        if p.tf is not None:
            imu_site = {p.imu.site: p.imu.frame_id} if p.imu else {}
            self.frames = RobotFrames(self.model, p.tf, p.base_body, p.base_frame,
                                      p.odom_frame, imu_site, p.position_joints)
        self.started = False
        self.goal_time_ns: int | None = None
        self.teleported = None  # the last /cosim/set_pose applied

    def step(self, tick: Tick, inputs: dict[str, Any]) -> dict[str, Any]:
        """Integrate one period (except at the first activation) and publish the state."""
        if self.swarm is not None:
            return self.swarm.step(tick, inputs)
        self._position_command(inputs.get(JOINT_COMMANDS))
        first = not self.started
        real = inputs.get(MIRROR_TOPIC)
        joints = inputs.get(MIRROR_JOINTS_TOPIC)
        if real is not None and real.header.frame_id:  # a twin: the real robot's pose, as is
            self._mirror(real, joints)
        elif self.started:
            if self.drive is None:
                self._integrate_fixed()
            else:
                self._integrate(*m.twist_of(inputs.get(CMD_VEL)))
            self._derive()
        self.started = True
        self._teleport(inputs.get(SET_POSE_TOPIC))
        self._check_goal(tick)
        out = self._publish()
        if first and self.frames is not None:
            out["/tf_static"] = TFMessage(transforms=self.frames.static)
        return out

    def _integrate(self, v: float, w: float) -> None:
        ctrl, (left_act, right_act) = self.data.ctrl, self.wheel_act
        for _ in range(self.substeps):
            ctrl[left_act], ctrl[right_act] = self.drive.update(v, w, self.dt)
            mujoco.mj_step(self.model, self.data)
            self.collisions.update(self.data)

    def _integrate_fixed(self) -> None:
        for _ in range(self.substeps):
            mujoco.mj_step(self.model, self.data)
            self.collisions.update(self.data)

    def _base_pose(self) -> np.ndarray:
        """The base's (x, y, z, qw, qx, qy, qz): its free joint, or its fixed world pose."""
        if self.mobile:
            return self.data.qpos[self.qadr:self.qadr + 7]
        return np.concatenate([self.data.xpos[self.base], self.data.xquat[self.base]])

    def _derive(self) -> None:
        """Bring what mj_step leaves one substep behind (it computes sensors and body poses
        before integrating) up to the state being published. Neither call changes what
        the next mj_step computes: that starts with mj_forward of the same state."""
        if self.imu is not None:
            mujoco.mj_forward(self.model, self.data)
        elif self.frames is not None and self.frames.needs_kinematics:
            mujoco.mj_kinematics(self.model, self.data)

    def _mirror(self, odom: Odometry, joints: JointState | None) -> None:
        """Place the base at the real robot's planar pose with its velocities (z, roll and
        pitch stay on the floor); nothing is integrated, the contacts are counted there."""
        p, q = odom.pose.pose.position, odom.pose.pose.orientation
        yaw = m.yaw_of(np.array([q.w, q.x, q.y, q.z]))
        base = self.data.qpos[self.qadr:self.qadr + 7]
        base[:2] = p.x, p.y
        base[3:] = np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)
        v, w = odom.twist.twist.linear, odom.twist.twist.angular  # in the base frame
        vel = self.data.qvel[self.vadr:self.vadr + 6]
        vel[:] = (v.x * np.cos(yaw) - v.y * np.sin(yaw), v.x * np.sin(yaw) + v.y * np.cos(yaw),
                  0.0, 0.0, 0.0, w.z)
        self.drive.v, self.drive.w = v.x, w.z
        if joints is not None:
            self._mirror_joints(joints)
        mujoco.mj_forward(self.model, self.data)
        self.collisions.update(self.data)

    def _mirror_joints(self, msg: JointState) -> None:
        """The real robot's joint positions (and velocities, where given) for the joints
        this robot has by name; others are left as they are."""
        index = {name: i for i, name in enumerate(self.joint_names)}
        for j, name in enumerate(msg.name):
            i = index.get(name)
            if i is None:
                continue
            if j < len(msg.position):
                self.data.qpos[self.joint_q[i]] = msg.position[j]
            if j < len(msg.velocity):
                self.data.qvel[self.joint_v[i]] = msg.velocity[j]

    def _teleport(self, msg: Any) -> None:
        """Put the base at rest at the request's x, y and yaw (z, roll and pitch stay on the
        floor), so this tick publishes it. The external node publishes its latest message at
        every activation: each request (its description says which) applies once."""
        if msg is None or not msg.name or msg == self.teleported or not self.mobile:
            return
        self.teleported = msg
        p, q = msg.pose.position, msg.pose.orientation
        yaw = m.yaw_of(np.array([q.w, q.x, q.y, q.z]))
        base = self.data.qpos[self.qadr:self.qadr + 7]
        base[:2] = p.x, p.y
        base[3:] = np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)
        self.data.qvel[:] = 0.0
        self.drive.v = self.drive.w = 0.0
        mujoco.mj_forward(self.model, self.data)

    def _check_goal(self, tick: Tick) -> None:
        """Ground truth: the robot is within the scenario goal's tolerances, or its joints
        within the joint goal's tolerances of their positions and of rest (sticky)."""
        if self.goal_time_ns is not None:
            return
        joint_goal = self.config.joint_goal
        if joint_goal is not None:
            target = np.fromiter(joint_goal["positions"].values(), dtype=np.float64)
            d = self.data
            if (np.all(np.abs(d.qpos[self.goal_q] - target) <= joint_goal["tolerance"])
                    and np.all(np.abs(d.qvel[self.goal_v]) <= joint_goal["speed_tolerance"])):
                self.goal_time_ns = tick.time_ns
            return
        goal = self.config.goal
        if goal is None or not self.mobile:
            return
        q = self.data.qpos[self.qadr:self.qadr + 7]
        yaw_error = (m.yaw_of(q[3:7]) - goal["yaw"] + np.pi) % (2 * np.pi) - np.pi
        if (np.hypot(q[0] - goal["x"], q[1] - goal["y"]) <= goal["position_tolerance"]
                and abs(yaw_error) <= goal["yaw_tolerance"]):
            self.goal_time_ns = tick.time_ns

    def _position_command(self, msg: Float64MultiArray | None) -> None:
        """Set the position servos' targets; a command of the wrong length is refused with a
        note (once for each new such command: the input repeats at every activation)."""
        if msg is None:
            return
        if len(msg.data) != len(self.position_act):
            if msg != self.refused_command:
                self.refused_command = msg
                self.note(f"{JOINT_COMMANDS} refused: it carries {len(msg.data)} positions, "
                          f"this robot takes {len(self.position_act)} "
                          f"{list(self.params.position_joints)}; the joints keep their targets")
            return
        self.data.ctrl[self.position_act] = np.asarray(msg.data, dtype=np.float64)

    def _publish(self) -> dict[str, Any]:
        d, p = self.data, self.params
        base_q = self._base_pose()
        base_v = d.qvel[self.vadr:self.vadr + 6] if self.mobile else np.zeros(6)
        effort = d.qfrc_actuator[self.joint_v]
        out = {
            ODOM: m.odometry(base_q, base_v, p.odom_frame, p.base_frame),
            JOINT_STATES: m.joint_state(self.joint_names, d.qpos[self.joint_q],
                                           d.qvel[self.joint_v], effort),
            "/cosim/world_state": m.world_state(d.qpos, d.qvel),
        }
        if self.frames is not None:
            out["/tf"] = TFMessage(transforms=self.frames.dynamic(d, base_q))
        if self.imu is not None:
            out["/imu"] = self.imu.measure(d)
        return out

    def metrics(self) -> dict[str, float]:
        """Collision events, the ground-truth planar pose, and whether it reached the goal."""
        if self.swarm is not None:
            return self.swarm.metrics()
        q = self._base_pose()
        out = {"collisions": float(self.collisions.events), "x": float(q[0]),
               "y": float(q[1]), "yaw": m.yaw_of(q[3:7])}
        if self.config.goal is not None or self.config.joint_goal is not None:
            out["arrived"] = float(self.goal_time_ns is not None)  # ground truth, sticky
        return out
