"""The controller manager node: ros2_control's standard controllers, configured by the user's
own controllers file, stepped in lockstep between the physics node and the ROS 2 world.

It runs at the file's ``update_rate`` (the node's ``rate`` must be that rate). At every
activation it reads the hardware's joint state (``nodes.ros2_control.hardware``: physics'
/joint_states, which the plan wires to ``/cosim/hardware_states``, ``hardware_role``),
applies controller switches, gives each active controller the messages of its topics and
updates it (``nodes.ros2_control.manager``), and writes the commands to the hardware
(physics' /joint_commands and /cmd_vel, wired likewise).

Each controller's topics are its type's (``nodes/ros2_control/controllers/``), ``~/x`` under
its name, as ros2_controllers' Jazzy documentation gives them. An inactive controller
claims nothing, is not updated and publishes nothing; as lockstep wants a message on every
declared topic at every activation, its topics carry an empty message of their type then
(a JointTrajectoryControllerState with no joints, an Odometry with no frame).

Switches (controller_manager/switch_controller) enter on ``/controller_manager/cosim/switch``
(std_msgs/String: ``+name`` activates, ``-name`` deactivates), and so do load_controller,
unload_controller and configure_controller (``load:name``, ``unload:name``,
``configure:name``), each a line with its request id (``nodes.ros2_control.requests``).
The metrics report each controller's state and the trajectory controllers' goals, which the
orchestrator's controller manager services answer from.
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

from geometry_msgs.msg import Twist
from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, String

from nodes.contract import StepNode, Tick
from nodes.ros2_control import config as c
from nodes.ros2_control.hardware import (
    BASE_COMMAND,
    HARDWARE_COMMANDS,
    HARDWARE_STATES,
    TopicHardware,
    hardware_info,
    unservable,
)
from nodes.ros2_control.interface import NS_PER_S, Fresh
from nodes.ros2_control.manager import ControllerManager, claim_conflict, load, resolve
from nodes.ros2_control.registry import served_types
from nodes.ros2_control.requests import apply_request, request_lines

SWITCH_TOPIC = "/controller_manager/cosim/switch"
SWITCH_TYPE = "std_msgs/msg/String"  # '+name' activates, '-name' deactivates, space-separated


class ControllerManagerParams(BaseModel):
    """The controllers file and the joints the physics node takes commands for."""

    model_config = ConfigDict(extra="forbid")
    controllers: str = Field(description="the ros2_control controllers YAML file "
                             "(controller_manager: ros__parameters: ...), relative to the "
                             "scenario file")
    command_joints: list[str] | None = Field(
        None, description="the physics node's position_joints, in its order (what "
        "/joint_commands carries); default: the robot's commanded joints, in its order")
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


def message_type_name(cls: type) -> str:
    """'std_msgs/msg/Float64MultiArray' of a generated message class."""
    package, kind = cls.__module__.split(".")[:2]
    return f"{package}/{kind}/{cls.__name__}"


def at_start(params: ControllerManagerParams, file: c.ControllersFile) -> list[str]:
    """The controllers active from the start: every one not listed in ``inactive``."""
    return [e.name for e in file.controllers if e.name not in params.inactive]


class ControllerManagerNode(StepNode):
    """ros2_control's controller manager with its standard controllers, in lockstep."""

    Params = ControllerManagerParams
    needs_world = True
    hardware_role = True  # physics is wired to it by the plan (plan/hardware_wiring.py)

    @classmethod
    def outputs(cls, params: ControllerManagerParams) -> dict[str, type]:
        """Every controller's published topics and the hardware's commands."""
        out: dict[str, type] = {}
        for name, ctrl in load(read(params)).items():
            if ctrl is None:
                continue
            out.update({resolve(name, t): m for t, m in ctrl.publications().items()})
            if ctrl.claim().command:
                out[BASE_COMMAND if ctrl.drives_base else HARDWARE_COMMANDS] = (
                    Twist if ctrl.drives_base else Float64MultiArray)
        return out

    @classmethod
    def _subscriptions(cls, params: ControllerManagerParams) -> dict[str, type]:
        return {resolve(name, t): m for name, ctrl in load(read(params)).items()
                if ctrl is not None for t, m in ctrl.subscriptions().items()}

    @classmethod
    def client_inputs(cls, params: ControllerManagerParams) -> dict[str, str]:
        """What ROS 2 clients feed an interactive run: each controller's command topics, the
        trajectory controllers' action goals, and controller switches."""
        return {SWITCH_TOPIC: SWITCH_TYPE, **{t: message_type_name(m) for t, m in
                                              cls._subscriptions(params).items()}}

    @classmethod
    def accepted_inputs(cls, params: ControllerManagerParams) -> set[str]:
        """The hardware's joint state and what clients feed."""
        return {HARDWARE_STATES, *cls.client_inputs(params)}

    @classmethod
    def input_types(cls, params: ControllerManagerParams) -> dict[str, type]:
        """JointState from physics; the command topics' types."""
        return {HARDWARE_STATES: JointState, SWITCH_TOPIC: String,
                **cls._subscriptions(params)}

    @classmethod
    def world_problems(cls, params: ControllerManagerParams, model, goal
                       ) -> list[tuple[str, str, str]]:
        """``inactive`` names controllers of the file, and every controller active from the
        start is of a type cosim runs."""
        file = read(params)
        names = [e.name for e in file.controllers]
        for name in params.inactive:
            if name not in names:
                return [("params.inactive", f"{name!r} is not a controller of "
                         f"{file.file.name}.", "one of " + ", ".join(names) + ".")]
        for entry in file.unserved:
            if entry.name in at_start(params, file):
                return [("params.inactive", f"{file.file.name}: controller {entry.name!r} has "
                         f"type {entry.type!r}, which cosim cannot run, and would be "
                         "activated at the start.", f"{entry.name} in params.inactive (it "
                         "loads and stays inactive), or a type cosim runs: "
                         + ", ".join(served_types()) + ".")]
        return []

    @classmethod
    def world_warnings(cls, params: ControllerManagerParams, model, goal, start
                       ) -> list[tuple[str, str]]:
        """The controllers whose type cosim cannot run: they load, and cannot be active."""
        file = read(params)
        return [("params.controllers", f"{file.file.name}: controller {e.name!r} of type "
                 f"{e.type!r} is loaded, and cosim cannot run its type: its activation is "
                 "refused.") for e in file.unserved]

    @classmethod
    def robot_problems(cls, params: ControllerManagerParams, robot, model
                       ) -> list[tuple[str, str, str]]:
        """Every interface a controller active from the start claims is one the robot's
        hardware has (a command interface one of its MuJoCo actuators realises; an inactive
        one loads, and its activation is refused, as upstream's), and no command interface
        is claimed by two controllers active from the start."""
        file = read(params)
        info = hardware_info(model, robot, params.command_joints)
        if params.command_joints is not None:
            found = {j.name for j in info.commands}
            for name in params.command_joints:
                if name not in found:
                    return [("params.command_joints", f"joint {name!r} has no actuator in the "
                             "world.", "joints with actuators: " + ", ".join(
                                 info.command_interfaces()) + ".")]
        controllers = load(file)
        starting = at_start(params, file)
        for name, ctrl in controllers.items():
            if ctrl is None or name not in starting:
                continue
            for problem, accepted in info.problems(ctrl.claim()):
                return [("params.controllers", f"{file.file.name}: {name}: {problem}",
                         accepted)]
        conflict = claim_conflict(controllers, starting)
        if conflict:
            return [("params.controllers", f"{file.file.name}: {conflict}.", "one active "
                     "controller per command interface (list the others in params.inactive).")]
        return []

    @classmethod
    def natural_rate(cls, params: ControllerManagerParams) -> int:
        """The controllers file's update_rate."""
        return read(params).update_rate

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
        """Read the file, load and configure the controllers, find the robot's hardware."""
        from nodes.physics.world import load_model

        self.file = read(self.params)
        model = load_model(self.config.world, self.config.layout)
        robot = self.config.robots[0] if self.config.robots else None
        info = hardware_info(model, robot, self.params.command_joints)
        self.manager = ControllerManager(self.file)
        self.manager.unservable = unservable(self.manager.controllers, info)
        self.declared = self.outputs(self.params)
        self.hardware = TopicHardware(info, HARDWARE_COMMANDS in self.declared,
                                      BASE_COMMAND in self.declared)
        self.fresh = Fresh()
        self.request, self.refused = 0, []  # the newest request handled; refused this tick
        self.first = True
        for note in self.manager.notes():
            self.note(note)
        for name, why in self.manager.unservable.items():
            self.note(f"{name}: {why}: it is loaded, and its activation is refused.")

    def step(self, tick: Tick, inputs: dict[str, Any]) -> dict[str, Any]:
        """One update of the controller manager."""
        hw = inputs.get(HARDWARE_STATES)
        if hw is None:
            raise RuntimeError(f"the controller manager needs {HARDWARE_STATES} (physics' "
                               "/joint_states, wired by the plan) at every update")
        self.hardware.read(hw)
        state = self.hardware.state
        commands: dict[str, float] = {}
        if self.first:
            self.hardware.start()
            commands.update(self.manager.activate(at_start(self.params, self.file),
                                                  state).commands)
            self.first = False
        commands.update(self._switch(inputs.get(SWITCH_TOPIC)))
        done = self.manager.update(tick.time_ns, self.config.period_ns, inputs,
                                   self.config.held_inputs)
        for note in done.notes:
            self.note(note)
        commands.update(done.commands)
        out = {**done.published, **self.hardware.write(commands)}
        # lockstep wants one message per declared topic and activation: an inactive
        # controller's topics carry an empty message of their type, nothing of the controller
        for topic, cls in self.declared.items():
            if topic not in out:
                out[topic] = cls()
        return out

    def _switch(self, msg) -> dict[str, float]:
        """The requests of the switch topic (``nodes.ros2_control.requests``) not handled
        before: a request with an id once, one without when the message is new."""
        self.refused = []
        if msg is None:
            return {}
        new = self.fresh(SWITCH_TOPIC, msg)
        commands: dict[str, float] = {}
        for rid, body in request_lines(msg.data):
            if (rid is None and not new) or (rid is not None and rid <= self.request):
                continue
            self.request = max(self.request, rid or 0)
            done, why = apply_request(self.manager, body, self.hardware.state)
            commands.update(done)
            if why:
                self.note(why if rid is None else f"{why} (request {rid})")
                if rid is not None:
                    self.refused.append(rid)
        return commands

    def metrics(self) -> dict[str, float]:
        """Each controller's state (active:<name> 1 or 0; state:<name> 0 unloaded,
        1 unconfigured, 2 inactive, 3 active) and each trajectory controller's
        newest action goal: its number, state (0 none, 1 active, 2 succeeded, 3 aborted,
        4 cancelled or preempted), result code and the joint that broke a tolerance; the
        newest request handled (``request``) and those refused at this tick
        (``refused:<id>`` 1)."""
        return {**self.manager.metrics(), "request": float(self.request),
                **{f"refused:{r}": 1.0 for r in self.refused}}
