"""The physics node: a MuJoCo world with its robots (one, unnamed, without a robots:
section: a swarm of one, stepped by nodes.physics.swarm), each as the one robot model
describes it (``NodeConfig.robots``, read from the description by descriptions.robot_reader
with the names these parameters give): a differential-drive base (or a base fixed to the
world, ``wheel_joints: null``: an arm on the floor) and position-servoed joints (the pan-tilt
head; the six joints of an arm). In a swarm every topic below is each robot's under its
namespace (``/ROBOT/odom``), but /tf, /tf_static and /cosim/... (shared).

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
too; /cosim/world_edits (std_msgs/String, optional: SpawnEntity and DeleteEntity requests of
an interactive run's clients, every one so far, as JSON) puts objects into the world and
takes them out, as the scenario's ``events:`` do at their ticks
(nodes.physics.world_events).
Outputs at tick k are the state at time t_k: tick 0 publishes the initial state, every later
activation integrates one node period (a whole number of world timesteps) and publishes:
/odom, /joint_states, /cosim/world_state, /tf (nodes.physics.frames) and /imu
(nodes.physics.imu); /tf_static once, at the first activation, latched.

A robot's controller manager runs in this step (``controller_manager``, set by the plan from
the scenario's ``ros2_control`` node or ``robots.controllers``: nodes.ros2_control.hosted):
after integrating up to the tick it reads the joints from MjData, updates the controllers and
writes their commands to the actuators, at every n-th activation where its update_rate is this
node's rate / n (``output_periods``: its topics then too); the controllers' topics are this
node's (each robot's under its namespace), a joint state broadcaster's /joint_states the
robot's, and /joint_commands and /cmd_vel give way to the controllers that command the joints
and wheels.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from dataclasses import replace
from fractions import Fraction
from typing import Any

import mujoco
from geometry_msgs.msg import Twist, TwistStamped
from nav_msgs.msg import Odometry
from pydantic import BaseModel, ConfigDict, Field
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Float64MultiArray, String
from tf2_msgs.msg import TFMessage

from descriptions.robot_model import RobotModel
from descriptions.world_geometry import robot_footprint_radius, static_obstacles
from nodes.contract import StepNode, Tick
from nodes.physics.described_rig import ROBOT_DESCRIPTION
from nodes.physics.frames import TfParams, frame_problems, on_robot
from nodes.physics.imu import ImuParams, imu_problems
from nodes.physics.swarm import SwarmPhysics, robot_params
from nodes.physics.world import (
    NS_PER_S,
    load_model,
    robots_of,
    start_joints,
    substeps,
    timestep_ns,
)
from nodes.physics.world_events import LiveWorld
from nodes.ros2_control import hosted
from nodes.ros2_control.hosted import HostedManagerParams
from plan.interactive import SET_POSE_TOPIC, WORLD_EDITS_TOPIC
from plan.obstacles import place_problem
from plan.timeutil import divides_rate, format_ns, whole_divisions
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
    robot_description: bool = Field(False, description="publish a URDF robot's expanded URDF "
                                     "on /robot_description (std_msgs/String, latched)")
    threads: int = Field(1, ge=1, le=256, description=(
        "threads of MuJoCo's engine pool (collision and the islands' constraint solving "
        "in parallel); the state is the same at any count, so the digest is too. Pays off "
        "from a few hundred robots in one world (bench/README.md)"))
    controller_manager: HostedManagerParams | None = Field(None, description=(
        "each robot's controller manager, run in this node's step at its rate (set by the "
        "plan from the scenario's ros2_control node or robots.controllers; not written by "
        "hand)"))


class PhysicsNode(StepNode):
    """MuJoCo stepping, diff-drive and joint position control, odometry, collision counting:
    for every robot of the world (nodes.physics.swarm), one without a robots: section."""

    Params = PhysicsParams
    needs_world = True
    every_robot = True
    type_keys = {CMD_VEL: "params.enable_stamped_cmd_vel"}

    @classmethod
    def outputs(cls, params: PhysicsParams) -> dict[str, type]:
        """Odometry, joint states, the world state that sensor nodes mirror, /tf and /imu."""
        out = {ODOM: Odometry, JOINT_STATES: JointState,
               "/cosim/world_state": Float64MultiArray}
        if params.tf is not None:
            out["/tf"] = TFMessage
        if params.imu is not None:
            out["/imu"] = Imu
        if params.controller_manager is not None:  # the controllers' topics, a robot's
            out.update(hosted.publications(params.controller_manager))
        return out

    @classmethod
    def output_periods(cls, params: PhysicsParams) -> dict[str, Any]:
        """The outputs published at a period of their own (topic -> ns): the controllers'
        topics, at the controller manager's update_rate (physics' rate / n: every n-th
        activation, ``plan.schedule``)."""
        return _at_manager_rate(params, hosted.publications)

    @classmethod
    def input_periods(cls, params: PhysicsParams) -> dict[str, Any]:
        """The inputs taken at a period of their own (topic -> ns): the controller manager's
        (its switch topic, its controllers' commands and goals), at its updates only."""
        return _at_manager_rate(params, hosted.subscriptions)

    @classmethod
    def latched_outputs(cls, params: PhysicsParams) -> dict[str, type]:
        """/tf_static: the robot's fixed frames, once; /robot_description: a URDF robot's
        expanded URDF (``robot_description``), once."""
        out: dict[str, type] = {"/tf_static": TFMessage} if params.tf is not None else {}
        if params.robot_description:
            out[ROBOT_DESCRIPTION] = String
        return out

    @classmethod
    def input_types(cls, params: PhysicsParams) -> dict[str, type]:
        """/cmd_vel as Twist, or TwistStamped with ``enable_stamped_cmd_vel``."""
        twist = TwistStamped if params.enable_stamped_cmd_vel else Twist
        out = {CMD_VEL: twist, MIRROR_TOPIC: Odometry, MIRROR_JOINTS_TOPIC: JointState,
               WORLD_EDITS_TOPIC: String}
        if params.controller_manager is not None:
            out.update(hosted.subscriptions(params.controller_manager))
        return out

    @classmethod
    def client_inputs(cls, params: PhysicsParams) -> dict[str, str]:
        """What ROS 2 clients feed the robot's controller manager (switches, its controllers'
        command topics and goals), if it has one."""
        if params.controller_manager is None:
            return {}
        return hosted.client_inputs(params.controller_manager)

    @classmethod
    def description_names(cls, params: PhysicsParams) -> dict[str, Any]:
        """The robot's base, drive, position joints, IMU (site, frame and its sensors) and
        the sites and cameras TF hangs frames on, as the parameters name them: an MJCF
        robot's model is read by them."""
        tf = params.tf
        names: dict[str, Any] = {
            "base_body": params.base_body, "base_frame": params.base_frame,
            "wheel_joints": params.wheel_joints, "wheel_actuators": params.wheel_actuators,
            "position_joints": tuple(params.position_joints),
            "position_actuators": tuple(params.position_actuators),
            "tf_sites": () if tf is None else tuple(tf.sites.items()),
            "tf_cameras": () if tf is None else tuple(
                (c.camera, c.link_frame, c.color_optical_frame, c.depth_optical_frame)
                for c in tf.cameras)}
        if params.imu is not None:
            names.update(imu_site=params.imu.site, imu_frame=params.imu.frame_id,
                         imu_gyro=params.imu.gyro, imu_accelerometer=params.imu.accelerometer,
                         imu_orientation=params.imu.orientation)
        return names

    @classmethod
    def world_problems(cls, params: PhysicsParams, model, goal, robot: str = "",
                       described: RobotModel | None = None) -> list[tuple[str, str, str]]:
        """The robot's bodies and joints exist; the start pose is inside the world, clear of
        every obstacle by the robot's footprint radius. In a swarm, robot ``robot``'s copy
        (each is checked as the first one is); ``described``: its model where a description
        reader made it (the plan's, as the run gives it), whose names are the model's."""
        if params.robot_description and described is None:
            return [("params.robot_description", "the robot is not described by a URDF, "
                     "xacro or USD robot, so there is no URDF to publish.", "robot_description: "
                     "true with a robots: description that is a .urdf, .xacro, .urdf.xacro or a "
                     "USD robot (.usd, .usda, .usdc).")]
        if described is not None:  # its names are its model's, checked when it was loaded
            if params.imu is not None and described.sensor("imu") is None:
                return [("params.imu", "the robot has no IMU: its description hangs none on a "
                         "link.", "imu: null, or an IMU on a link: robots.urdf.sensors or "
                         "robots.usd.sensors (imu: LINK), or a Gazebo imu sensor tag.")]
            return []
        if robot:
            return cls.world_problems(robot_params(params, robot), model, goal)
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
        manager = params.controller_manager
        if manager is not None:
            rate = hosted.read(manager).update_rate
            if not divides_rate(rate, period_ns):
                hz = NS_PER_S / Fraction(period_ns)
                return [("rate", f"the controller manager runs in this node's step, at every "
                         f"n-th activation for a whole n, and its controllers file "
                         f"({manager.controllers}) says controller_manager.ros__parameters."
                         f"update_rate: {rate}, this node runs at {float(hz):g} Hz "
                         f"(ratio {float(hz / rate):g}).", f"update_rate: one of "
                         f"{whole_divisions(hz)} (this rate / n) in the controllers file, or "
                         f"rate: a whole multiple of {rate} here.")]
        if period_ns % step == 0:
            return []
        fits = [NS_PER_S // (k * step) for k in range(1, 1000)
                if NS_PER_S % (k * step) == 0][:5]
        example = f", e.g. {', '.join(map(str, fits))} Hz" if fits else ""
        period = f"{period_ns} ns" if isinstance(period_ns, int) else format_ns(period_ns)
        return [("rate", f"the period {period} is not a whole number of the world's "
                 f"timesteps ({step} ns, <option timestep={model.opt.timestep!r}>): physics "
                 "integrates whole timesteps in each period.",
                 f"a rate whose period is a multiple of {step} ns{example}; or change "
                 "<option timestep> in the world.")]

    @classmethod
    def accepted_inputs(cls, params: PhysicsParams) -> set[str]:
        """Joint position commands and clients' world edits (SpawnEntity, DeleteEntity);
        with a drive, velocity commands, teleports and a real robot's pose (a twin) too; in
        a swarm, each robot's (``plan.robots.per_robot``)."""
        mobile = ({CMD_VEL, SET_POSE_TOPIC, MIRROR_TOPIC, MIRROR_JOINTS_TOPIC}
                  if params.wheel_joints is not None else set())
        out = mobile | {JOINT_COMMANDS, WORLD_EDITS_TOPIC}
        if params.controller_manager is not None:  # the controllers command the hardware
            joints, base = hosted.takes_hardware(params.controller_manager)
            out -= {JOINT_COMMANDS} if joints else set()
            out -= {CMD_VEL} if base else set()
            out |= set(hosted.subscriptions(params.controller_manager))
        return out

    def setup(self) -> None:
        """Load the world, check the timestep against the period and place the robots."""
        world = self.config.world
        live = None
        if self.config.events:  # a world that changes: kept as a spec to recompile
            live = LiveWorld(world, self.config.layout, self.config.events, self.note)
            self.model = live.model
        else:
            self.model = load_model(world, self.config.layout)
            if self.params.controller_manager is not None and any(
                    a.modes for r in self.config.robots for a in r.actuated):
                # a controller's activation may switch an actuator's mode in the model
                # (nodes.ros2_control.hosted): this node's own, not the process's cached one
                self.model = copy.copy(self.model)
        self.data = mujoco.MjData(self.model)
        if self.params.threads > 1:
            mujoco.mju_threadpool(self.data, self.params.threads)
        self.substeps = substeps(self.model, world, self.config.period_ns)
        self.dt = timestep_ns(self.model, world) / 1e9
        robots = robots_of(self.config, self.description_names(self.params))
        start_joints(self.model, self.data, robots)  # the <ros2_control> initial_values
        self.swarm = SwarmPhysics(self.model, self.data, self.params,
                                  replace(self.config, robots=robots), self.rng, self.substeps,
                                  self.dt, self.note, live)

    def step(self, tick: Tick, inputs: dict[str, Any]) -> dict[str, Any]:
        """Integrate one period (except at the first activation), apply the scenario's
        events due at the tick, and publish the state."""
        out = self.swarm.step(tick, inputs)
        self.model, self.data = self.swarm.model, self.swarm.data  # recompiled by an event
        return out

    def metrics(self) -> dict[str, float]:
        """Collision events, the ground-truth planar pose, and whether it reached the goal
        (a swarm: per robot, and the swarm's totals); a controller manager's
        (``controller_manager/...``, ``ROBOT/controller_manager/...`` in a swarm)."""
        return self.swarm.metrics()


def _at_manager_rate(params: PhysicsParams, topics_of: Callable[[Any], Any]) -> dict[str, Any]:
    """topic -> the hosted controller manager's update period (ns), for each of the
    topics ``topics_of`` finds in its settings (its publications or its subscriptions);
    {} without a manager."""
    if params.controller_manager is None:
        return {}
    period = hosted.manager_period_ns(params.controller_manager, None)
    return {topic: period for topic in topics_of(params.controller_manager)}
