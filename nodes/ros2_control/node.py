"""The controller manager node: ros2_control's standard controllers, configured by the user's
own controllers file, stepped in lockstep between the physics node and the ROS 2 world.

It runs at the file's ``update_rate`` (the node's ``rate`` must be that rate). At every
activation it reads the hardware's joint state (physics' /joint_states, remapped to
``/cosim/hardware_states`` in the scenario: the joint state broadcaster publishes
``/joint_states``), applies controller switches and the commands that arrived, updates every
active controller and writes the joints: positions on ``/cosim/hardware_commands`` (physics'
/joint_commands remapped: its ``position_joints``, in ``command_joints`` order; a joint no
active controller commands keeps its last command) and the base twist on
``/cosim/base_command`` (physics' /cmd_vel remapped: the wheel speeds of the diff drive
controller, as the physics node's drive realises them).

Topics under each controller's name, as ros2_controllers' Jazzy documentation gives them:

- joint_state_broadcaster: ``/joint_states`` and ``/dynamic_joint_states`` (``~/...`` with
  ``use_local_topics``);
- joint_trajectory_controller: ``~/joint_trajectory`` in, ``~/controller_state`` out, and the
  ``~/follow_joint_trajectory`` action (served by the orchestrator, whose goals and cancels
  enter here at a tick boundary on ``~/cosim/goal``: an empty trajectory is a cancel);
- forward_command_controller, position_controllers/JointGroupPositionController: ``~/commands``;
- diff_drive_controller: ``~/cmd_vel`` (TwistStamped) in, ``~/odom`` out.

Switches (controller_manager/switch_controller) enter on ``/controller_manager/cosim/switch``
(std_msgs/String: ``+name`` activates, ``-name`` deactivates).
The metrics report each controller's state and the trajectory controllers' goals, which the
orchestrator's controller manager services answer from.
"""

from __future__ import annotations

import functools
import math
from pathlib import Path
from typing import Any

import mujoco
from builtin_interfaces.msg import Duration
from control_msgs.action import FollowJointTrajectory
from control_msgs.msg import DynamicJointState, JointTrajectoryControllerState
from geometry_msgs.msg import Twist, TwistStamped
from nav_msgs.msg import Odometry
from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, String
from trajectory_msgs.msg import JointTrajectory

from nodes.contract import StepNode, Tick
from nodes.ros2_control import config as c
from nodes.ros2_control import fast_messages as fast
from nodes.ros2_control.controllers import (
    DiffDrive,
    ForwardCommand,
    JointReading,
    TrajectoryController,
)
from nodes.ros2_control.trajectory import NS_PER_S

HARDWARE_STATES = "/cosim/hardware_states"
HARDWARE_COMMANDS = "/cosim/hardware_commands"  # physics' /joint_commands, remapped
BASE_COMMAND = "/cosim/base_command"  # physics' /cmd_vel, remapped
SWITCH_TOPIC = "/controller_manager/cosim/switch"
GOAL_SUFFIX = "/cosim/goal"
GOAL_TYPE = "control_msgs/action/FollowJointTrajectory_Goal"
SWITCH_TYPE = "std_msgs/msg/String"  # '+name' activates, '-name' deactivates, space-separated
GOAL_ID, CANCEL_ID = "cosim-goal-", "cosim-cancel-"  # + a number: the trajectory's frame_id


class ControllerManagerParams(BaseModel):
    """The controllers file and the joints the physics node takes commands for."""

    model_config = ConfigDict(extra="forbid")
    controllers: str = Field(description="the ros2_control controllers YAML file "
                             "(controller_manager: ros__parameters: ...), relative to the "
                             "scenario file")
    command_joints: list[str] | None = Field(
        None, description="the physics node's position_joints, in its order (what "
        "/joint_commands carries); default: every joint with a position actuator, in the "
        "world's actuator order")
    inactive: list[str] = Field([], description="controllers loaded but not active at the "
                                "start (as --inactive of the spawner)")

    @field_validator("controllers")
    @classmethod
    def _resolve(cls, value: str, info: ValidationInfo) -> str:
        base = Path((info.context or {}).get("scenario_dir", "."))
        path = (base / value).resolve()
        c.read_controllers_file(path)  # a ControllersFileError says what is wrong
        return str(path)


def read(params: ControllerManagerParams) -> c.ControllersFile:
    """The node's controllers file, read and checked (once per process and file)."""
    try:
        stat = Path(params.controllers).stat()
    except OSError:
        return c.read_controllers_file(params.controllers)  # says the file cannot be read
    return _read(params.controllers, stat.st_mtime_ns, stat.st_size)


@functools.lru_cache(maxsize=8)
def _read(path: str, mtime_ns: int, size: int) -> c.ControllersFile:
    return c.read_controllers_file(path)


class ControllerManagerNode(StepNode):
    """ros2_control's controller manager with its standard controllers, in lockstep."""

    Params = ControllerManagerParams
    needs_world = True

    @classmethod
    def outputs(cls, params: ControllerManagerParams) -> dict[str, type]:
        """The joints' commands and every controller's published topics."""
        out: dict[str, type] = {}
        for spec in read(params).controllers:
            if spec.type == c.JSB:
                local = f"/{spec.name}" if spec.params["use_local_topics"] else ""
                out[f"{local}/joint_states"] = JointState
                if spec.params["publish_dynamic_joint_states"]:
                    out[f"{local}/dynamic_joint_states"] = DynamicJointState
            elif spec.type == c.JTC:
                out[f"/{spec.name}/controller_state"] = JointTrajectoryControllerState
                out[HARDWARE_COMMANDS] = Float64MultiArray
            elif spec.type == c.DIFF_DRIVE:
                out[f"/{spec.name}/odom"] = Odometry
                out[BASE_COMMAND] = Twist
            else:
                out[HARDWARE_COMMANDS] = Float64MultiArray
        return out

    @classmethod
    def client_inputs(cls, params: ControllerManagerParams) -> dict[str, str]:
        """What ROS 2 clients feed an interactive run: each controller's command topic, the
        trajectory controllers' action goals, and controller switches."""
        fed = {SWITCH_TOPIC: SWITCH_TYPE}
        for spec in read(params).controllers:
            if spec.type == c.JTC:
                fed[f"/{spec.name}/joint_trajectory"] = "trajectory_msgs/msg/JointTrajectory"
                fed[f"/{spec.name}{GOAL_SUFFIX}"] = GOAL_TYPE
            elif spec.type in (c.FORWARD, c.GROUP_POSITION, c.GROUP_VELOCITY):
                fed[f"/{spec.name}/commands"] = "std_msgs/msg/Float64MultiArray"
            elif spec.type == c.DIFF_DRIVE:
                fed[f"/{spec.name}/cmd_vel"] = "geometry_msgs/msg/TwistStamped"
        return fed

    @classmethod
    def accepted_inputs(cls, params: ControllerManagerParams) -> set[str]:
        """The hardware's joint state and what clients feed."""
        return {HARDWARE_STATES, *cls.client_inputs(params)}

    @classmethod
    def input_types(cls, params: ControllerManagerParams) -> dict[str, type]:
        """JointState from physics; the command topics' types."""
        types: dict[str, type] = {HARDWARE_STATES: JointState, SWITCH_TOPIC: String}
        for spec in read(params).controllers:
            if spec.type == c.JTC:
                types[f"/{spec.name}/joint_trajectory"] = JointTrajectory
                types[f"/{spec.name}{GOAL_SUFFIX}"] = FollowJointTrajectory.Goal
            elif spec.type == c.DIFF_DRIVE:
                types[f"/{spec.name}/cmd_vel"] = TwistStamped
            elif spec.type != c.JSB:
                types[f"/{spec.name}/commands"] = Float64MultiArray
        return types

    @classmethod
    def world_problems(cls, params: ControllerManagerParams, model, goal
                       ) -> list[tuple[str, str, str]]:
        """Every controller's joints are joints of the world, commanded through an interface
        the world has (a position actuator; a diff drive's wheels), no joint commanded by two
        active controllers, and inactive names controllers of the file."""
        spec_file = read(params)
        # in a robots: world every name is the robot's: 'mybot/wheel_left_joint'
        joints = {model.joint(j).name.rpartition("/")[2] for j in range(model.njnt)}
        positions = position_joints(model)
        commanded = params.command_joints if params.command_joints is not None else positions
        for name in commanded:
            if name not in positions:
                return [("params.command_joints", f"joint {name!r} has no position actuator "
                         "in the world.", "joints with position actuators: "
                         + ", ".join(positions) + ".")]
        names = [s.name for s in spec_file.controllers]
        for name in params.inactive:
            if name not in names:
                return [("params.inactive", f"{name!r} is not a controller of "
                         f"{spec_file.file.name}.", "one of " + ", ".join(names) + ".")]
        owner: dict[str, str] = {}
        for spec in spec_file.controllers:
            for joint in spec.joints:
                if joint not in joints:
                    return [("params.controllers", f"{spec_file.file.name}: {spec.name}: joint "
                             f"{joint!r} is not in the world.", "joints of the robot: "
                             + ", ".join(sorted(j for j in joints if j)) + ".")]
                if spec.type == c.DIFF_DRIVE:
                    continue
                if spec.type == c.JSB:
                    continue
                if spec.interface != "position" or joint not in commanded:
                    return [("params.controllers", f"{spec_file.file.name}: {spec.name}: "
                             f"joint {joint!r} has no {spec.interface} command interface in "
                             "cosim's hardware (its joints take positions through "
                             "/joint_commands).", "a position controller for joints of "
                             "command_joints: " + ", ".join(commanded) + ".")]
                if joint in owner and spec.name not in params.inactive \
                        and owner[joint] not in params.inactive:
                    return [("params.controllers", f"{spec_file.file.name}: joint {joint!r} "
                             f"is claimed by {owner[joint]!r} and {spec.name!r}, both active.",
                             "one active controller per joint (list the others in "
                             "params.inactive).")]
                owner[joint] = spec.name
        return []

    @classmethod
    def period_problems(cls, params: ControllerManagerParams, model, period_ns: int
                        ) -> list[tuple[str, str, str]]:
        """The node's rate is the file's update_rate."""
        rate = read(params).update_rate
        if period_ns * rate != NS_PER_S:
            return [("rate", f"the controllers file says update_rate: {rate}, the node "
                     f"runs at {float(NS_PER_S / period_ns):g} Hz.", f"rate: {rate}.")]
        return []

    def setup(self) -> None:
        """Read the file, build the controllers, find the world's joints."""
        from nodes.physics.world import load_model

        self.file = read(self.params)
        model = load_model(self.config.world, self.config.layout)
        self.command_joints = (list(self.params.command_joints)
                               if self.params.command_joints is not None
                               else position_joints(model))
        self.active = {s.name: s.name not in self.params.inactive for s in self.file.controllers}
        self.controllers: dict[str, Any] = {}
        for spec in self.file.controllers:
            if spec.type == c.JTC:
                self.controllers[spec.name] = TrajectoryController(spec)
            elif spec.type == c.DIFF_DRIVE:
                self.controllers[spec.name] = DiffDrive(spec, self._drive(model, spec))
            elif spec.type != c.JSB:
                self.controllers[spec.name] = ForwardCommand(spec)
        self.command: dict[str, float] = {}
        self.last_taken: dict[str, Any] = {}
        self.first = True
        self.dt = float(self.config.period_ns / NS_PER_S)  # a Fraction at 30 Hz
        for note in self.file.notes:
            self.note(note)

    def _drive(self, model, spec: c.ControllerSpec) -> tuple[float, float]:
        """(wheel radius, separation) of the physics node's drive: the robot model's where
        this node is a robot's (its drive's wheels), else read off the world's wheels."""
        from descriptions.robot_reader import wheel_geometry

        for robot in self.config.robots or ():
            drive = robot.drive
            if drive is not None:
                return drive.wheel_radius, drive.wheel_separation
        return wheel_geometry(model, spec.params["left"][0], spec.params["right"][0])

    def step(self, tick: Tick, inputs: dict[str, Any]) -> dict[str, Any]:
        """One update of the controller manager."""
        hw = inputs.get(HARDWARE_STATES)
        if hw is None:
            raise RuntimeError(f"the controller manager needs {HARDWARE_STATES} (physics' "
                               "/joint_states, remapped) at every update")
        state = {n: JointReading(p, v, e) for n, p, v, e in zip(
            hw.name, hw.position, _padded(hw.velocity, hw.name), _padded(hw.effort, hw.name),
            strict=True)}
        if self.first:
            self.command = {j: state[j].position for j in self.command_joints}
            for ctrl in self.controllers.values():
                if isinstance(ctrl, TrajectoryController):
                    ctrl.activate(state)
            self.first = False
        self._switch(inputs.get(SWITCH_TOPIC), state)
        now = tick.time_ns
        for name, ctrl in self.controllers.items():
            if not self.active[name]:
                continue
            if isinstance(ctrl, TrajectoryController):
                self._trajectory_inputs(ctrl, inputs, now, state)
                ctrl.update(now, state)
            elif isinstance(ctrl, ForwardCommand):
                msg = inputs.get(f"/{name}/commands")
                if msg is not None and (why := ctrl.take(list(msg.data))):
                    self.note(why)
            else:
                msg = inputs.get(f"/{name}/cmd_vel")
                if msg is not None:
                    ctrl.take(msg.twist.linear.x, msg.twist.angular.z, now)
            if not isinstance(ctrl, DiffDrive):
                self.command.update(ctrl.positions())
        return self._outputs(tick, state)

    def _fresh(self, topic: str, msg) -> bool:
        """Whether ``msg`` on ``topic`` is news: the external node publishes the latest
        message from outside at every activation, so one equal to the last is held, not sent
        again (its header stamp, the tick's, is left out of the comparison)."""
        if msg is None:
            return False
        key = (list(msg.joint_names), list(msg.points)) if isinstance(msg, JointTrajectory) \
            else msg
        if self.last_taken.get(topic) == key:
            return False
        self.last_taken[topic] = key
        return True

    def _switch(self, msg, state) -> None:
        if not self._fresh(SWITCH_TOPIC, msg):
            return
        known = set(self.active)
        words = msg.data.split()
        activate = [w[1:] for w in words if w.startswith("+")]
        deactivate = [w[1:] for w in words if w.startswith("-")]
        unknown = [n for n in [*activate, *deactivate] if n not in known]
        if unknown or len(activate) + len(deactivate) != len(words):
            self.note(f"switch_controller refused: {msg.data!r} names no controller "
                      f"{(unknown or words)[0]!r}")
            return
        for name in deactivate:
            self.active[name] = False
            ctrl = self.controllers.get(name)
            if isinstance(ctrl, TrajectoryController):
                ctrl.stop(state)
            elif isinstance(ctrl, DiffDrive):
                ctrl.take(0.0, 0.0, -1)
        for name in activate:
            if not self.active[name]:
                self.active[name] = True
                ctrl = self.controllers.get(name)
                if isinstance(ctrl, TrajectoryController):
                    ctrl.activate(state)
                elif isinstance(ctrl, ForwardCommand):
                    ctrl.command = None

    def _trajectory_inputs(self, ctrl: TrajectoryController, inputs, now: int, state) -> None:
        topic = inputs.get(f"/{ctrl.spec.name}/joint_trajectory")
        if self._fresh(f"/{ctrl.spec.name}/joint_trajectory", topic) and not _blank(topic):
            if ctrl.goal_state == 1:  # a topic message preempts an action goal
                ctrl.goal_state, ctrl.error_code = 4, 0
                ctrl.from_action = False
            if why := ctrl.take(topic, now, state):
                self.note(f"{ctrl.spec.name}/joint_trajectory refused: {why[1]}")
        goal = inputs.get(f"/{ctrl.spec.name}{GOAL_SUFFIX}")
        # the orchestrator names each goal and cancel in the trajectory's frame_id
        if goal is None or not goal.trajectory.header.frame_id.startswith("cosim-") or \
                not self._fresh(f"/{ctrl.spec.name}{GOAL_SUFFIX}",
                                goal.trajectory.header.frame_id):
            return
        if goal.trajectory.header.frame_id.startswith(CANCEL_ID):
            if ctrl.goal_state == 1:
                ctrl.stop(state)
                ctrl.goal_state, ctrl.from_action = 4, False
            return
        if ctrl.goal_state == 1:
            ctrl.goal_state = 4  # preempted by the newer goal
        ctrl.goal_seq += 1
        ctrl.error_joint = -1
        tolerances = goal_tolerances(ctrl, goal)
        why = ctrl.take(goal.trajectory, now, state, tolerances)
        if why:
            ctrl.goal_state, ctrl.error_code = 3, why[0]
            self.note(f"{ctrl.spec.name}/follow_joint_trajectory goal {ctrl.goal_seq} "
                      f"refused: {why[1]}")
            return
        ctrl.goal_state, ctrl.error_code, ctrl.from_action = 1, 0, True
        if not goal.trajectory.points:
            ctrl.goal_state = 2

    def _outputs(self, tick: Tick, state) -> dict[str, Any]:
        out: dict[str, Any] = {}
        twist = None
        for spec in self.file.controllers:
            ctrl = self.controllers.get(spec.name)
            if spec.type == c.JSB:
                local = f"/{spec.name}" if spec.params["use_local_topics"] else ""
                names = list(spec.joints) or list(state)
                readings = [state[n] for n in names]
                positions = [r.position for r in readings]
                velocities = [r.velocity for r in readings]
                efforts = [r.effort for r in readings]
                out[f"{local}/joint_states"] = fast.joint_state(names, positions, velocities,
                                                                efforts)
                if spec.params["publish_dynamic_joint_states"]:
                    out[f"{local}/dynamic_joint_states"] = fast.dynamic_joint_state(
                        names, positions, velocities, efforts)
            elif spec.type == c.JTC:
                out[f"/{spec.name}/controller_state"] = controller_state(ctrl, state)
            elif spec.type == c.DIFF_DRIVE:
                ctrl.update_odometry(state, self.dt)
                out[f"/{spec.name}/odom"] = diff_drive_odometry(ctrl)
                left, right = (ctrl.wheel_speeds(tick.time_ns, self.dt)
                               if self.active[spec.name] else (0.0, 0.0))
                radius, separation = ctrl.physics
                twist = Twist()
                twist.linear.x = radius * (left + right) / 2.0
                twist.angular.z = radius * (right - left) / separation
        if any(s.type not in (c.JSB, c.DIFF_DRIVE) for s in self.file.controllers):
            out[HARDWARE_COMMANDS] = fast.float64_array(
                [self.command[j] for j in self.command_joints])
        if twist is not None:
            out[BASE_COMMAND] = twist
        return out

    def metrics(self) -> dict[str, float]:
        """Each controller's state (active:<name> 1 or 0) and each trajectory controller's
        newest action goal: its number, state (0 none, 1 active, 2 succeeded, 3 aborted,
        4 cancelled or preempted), result code and the joint that broke a tolerance."""
        out = {f"active:{n}": float(a) for n, a in self.active.items()}
        for name, ctrl in self.controllers.items():
            if isinstance(ctrl, TrajectoryController):
                out[f"goal_seq:{name}"] = float(ctrl.goal_seq)
                out[f"goal_state:{name}"] = float(ctrl.goal_state)
                out[f"error_code:{name}"] = float(ctrl.error_code)
                out[f"error_joint:{name}"] = float(ctrl.error_joint)
        return out


def position_joints(model) -> list[str]:
    """The world's joints driven by a position actuator, in actuator order."""
    out = []
    for a in range(model.nu):
        if model.actuator_trntype[a] != mujoco.mjtTrn.mjTRN_JOINT:
            continue
        is_position = model.actuator_biastype[a] == mujoco.mjtBias.mjBIAS_AFFINE and \
            model.actuator_biasprm[a, 1] != 0.0
        if is_position:
            out.append(model.joint(int(model.actuator_trnid[a, 0])).name)
    return out


def _blank(msg: JointTrajectory) -> bool:
    """Whether ``msg`` is the external node's stand-in until a client sends a trajectory (a
    default-constructed one: no joints, no points): nothing was sent, so nothing is refused."""
    return not msg.joint_names and not msg.points and not msg.header.frame_id


def _padded(values, names) -> list[float]:
    return list(values) if len(values) == len(names) else [0.0] * len(names)


def goal_tolerances(ctrl: TrajectoryController, goal):
    """The goal's tolerances over the controller's defaults: a value 0 keeps the default,
    -1 means no tolerance (control_msgs/JointTolerance)."""
    tol = ctrl.defaults()
    index = {j: i for i, j in enumerate(ctrl.joints)}
    for entries, pos, vel in ((goal.path_tolerance, tol.path_position, tol.path_velocity),
                              (goal.goal_tolerance, tol.goal_position, tol.goal_velocity)):
        for entry in entries:
            i = index.get(entry.name)
            if i is None:
                continue
            if entry.position != 0.0:
                pos[i] = entry.position
            if entry.velocity != 0.0:
                vel[i] = entry.velocity
    t = goal.goal_time_tolerance
    if t.sec or t.nanosec:
        tol.goal_time_ns = t.sec * NS_PER_S + t.nanosec
    return tol


def controller_state(ctrl: TrajectoryController, state) -> JointTrajectoryControllerState:
    """~/controller_state: reference, feedback, error and output of every joint."""
    joints = ctrl.joints
    positions = [state[j].position for j in joints]
    velocities = [state[j].velocity for j in joints]
    feedback = fast.point(positions, velocities)
    desired = ctrl.desired
    if desired is None:
        reference, error, output = fast.point(), fast.point(), fast.point()
    else:
        reference = fast.point(desired.positions, desired.velocities, desired.accelerations)
        error = fast.point([d - f for d, f in zip(desired.positions, positions, strict=True)],
                           [d - f for d, f in zip(desired.velocities, velocities,
                                                  strict=True)])
        output = fast.point(desired.positions)
    return fast.controller_state(joints, reference, feedback, error, output)


def diff_drive_odometry(ctrl: DiffDrive) -> Odometry:
    """~/odom: the wheels' odometry in the controller's frames."""
    p, odo = ctrl.spec.params, ctrl.odometry
    msg = Odometry()
    msg.header.frame_id = p["odom_frame_id"]
    msg.child_frame_id = p["base_frame_id"]
    msg.pose.pose.position.x, msg.pose.pose.position.y = odo.x, odo.y
    msg.pose.pose.orientation.z = math.sin(odo.heading / 2.0)
    msg.pose.pose.orientation.w = math.cos(odo.heading / 2.0)
    msg.twist.twist.linear.x, msg.twist.twist.angular.z = odo.linear, odo.angular
    for i, value in enumerate(p["pose_covariance_diagonal"]):
        msg.pose.covariance[7 * i] = value
    for i, value in enumerate(p["twist_covariance_diagonal"]):
        msg.twist.covariance[7 * i] = value
    return msg


def duration(ns: int) -> Duration:
    """builtin_interfaces/Duration of ``ns``."""
    return Duration(sec=ns // NS_PER_S, nanosec=ns % NS_PER_S)
