"""The controller manager as a scenario declares it: ros2_control's standard controllers,
configured by the user's own controllers file (a ``ros2_control`` node, or the one
``robots.controllers`` adds for every robot).

It does not run as a node of its own: the plan folds it into the physics node
(``plan.hardware_wiring``), which runs it in its step over MjData
(``nodes.ros2_control.hosted``) at the file's ``update_rate``, which must be the physics
node's rate / n for a whole n (an update every n-th physics activation). This class holds
what the scenario's checks ask of it: its parameters, the controllers file's problems, what
the robot's hardware can serve, its topics.

Each controller's topics are its type's (``nodes/ros2_control/controllers/``), ``~/x`` under
its name, as ros2_controllers' Jazzy documentation gives them. An inactive controller
claims nothing, is not updated and publishes nothing; as lockstep wants a message on every
declared topic at every activation, its topics carry an empty message of their type then
(a JointTrajectoryControllerState with no joints, an Odometry with no frame).

Switches (controller_manager/switch_controller) enter on ``/controller_manager/cosim/switch``
(std_msgs/String: ``+name`` activates, ``-name`` deactivates), and so do load_controller,
unload_controller and configure_controller (``load:name``, ``unload:name``,
``configure:name``), each a line with its request id (``nodes.ros2_control.requests``).
The metrics (physics', under ``controller_manager/``) report each controller's state and the
trajectory controllers' goals, which the orchestrator's controller manager services answer
from.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator
from std_msgs.msg import String

from nodes.contract import StepNode, Tick
from nodes.ros2_control import config as c
from nodes.ros2_control.hardware import hardware_info
from nodes.ros2_control.interface import NS_PER_S
from nodes.ros2_control.manager import claim_conflict, load, resolve
from nodes.ros2_control.registry import served_types

SWITCH_TOPIC = "/controller_manager/cosim/switch"
SWITCH_TYPE = "std_msgs/msg/String"  # '+name' activates, '-name' deactivates, space-separated


class ControllerManagerParams(BaseModel):
    """The controllers file and the joints the physics node takes commands for."""

    model_config = ConfigDict(extra="forbid")
    controllers: str | list[str] = Field(
        description="the ros2_control controllers YAML file (controller_manager: "
        "ros__parameters: ...), relative to the scenario file; a list: files merged in order, "
        "a later file's parameter over an earlier's (as ros2_control_node's --params-file)")
    command_joints: list[str] | None = Field(
        None, description="the joints whose actuators the controllers may command, in "
        "order; default: the robot's commanded joints, in its order")
    inactive: list[str] = Field([], description="controllers loaded but not active at the "
                                "start (as --inactive of the spawner)")

    @field_validator("controllers")
    @classmethod
    def _resolve(cls, value: str | list[str], info: ValidationInfo) -> str | list[str]:
        base = Path((info.context or {}).get("scenario_dir", "."))
        paths = [str((base / v).resolve()) for v in ([value] if isinstance(value, str)
                                                     else value)]
        if not paths:
            raise ValueError("no controllers file given")
        c.read_controllers_file(*paths)  # a ControllersFileError says what is wrong
        return paths[0] if isinstance(value, str) else paths

    @property
    def files(self) -> list[str]:
        """The controllers files, in the order they are merged."""
        return [self.controllers] if isinstance(self.controllers, str) else self.controllers


class HostedManagerParams(ControllerManagerParams):
    """A controller manager run in the physics node's step: its node's parameters, and the
    name its metrics go under (``NAME/...``; ``ROBOT/NAME/...`` in a swarm)."""

    name: str = Field("controller_manager", description="the controller manager's name "
                      "(its metrics: NAME/key, ROBOT/NAME/key in a swarm)")


def takes_hardware(params: ControllerManagerParams) -> tuple[bool, bool]:
    """(whether a controller of the file commands joints, whether one drives the base's
    wheels): physics' own /joint_commands and /cmd_vel give way to them."""
    joints = base = False
    for ctrl in load(read(params)).values():
        if ctrl is not None and ctrl.claim().command:
            base |= ctrl.drives_base
            joints |= not ctrl.drives_base
    return joints, base


def read(params: ControllerManagerParams) -> c.ControllersFile:
    """The node's controllers file (its files merged), read and checked (once per process
    and content: ``config.read_controllers_file``)."""
    return c.read_controllers_file(*params.files)


def message_type_name(cls: type) -> str:
    """'std_msgs/msg/Float64MultiArray' of a generated message class."""
    package, kind = cls.__module__.split(".")[:2]
    return f"{package}/{kind}/{cls.__name__}"


def publications(params: ControllerManagerParams) -> dict[str, type]:
    """Every loaded controller's published topics, under the graph's names for one robot."""
    out: dict[str, type] = {}
    for name, ctrl in load(read(params)).items():
        if ctrl is not None:
            out.update({resolve(name, t): m for t, m in ctrl.publications().items()})
    return out


def subscriptions(params: ControllerManagerParams) -> dict[str, type]:
    """The switch topic and every loaded controller's subscribed topics, for one robot."""
    out: dict[str, type] = {SWITCH_TOPIC: String}
    for name, ctrl in load(read(params)).items():
        if ctrl is not None:
            out.update({resolve(name, t): m for t, m in ctrl.subscriptions().items()})
    return out


def client_inputs(params: ControllerManagerParams) -> dict[str, str]:
    """What ROS 2 clients feed an interactive run: controller switches, each controller's
    command topics and the trajectory controllers' action goals."""
    return {SWITCH_TOPIC: SWITCH_TYPE, **{t: message_type_name(m) for t, m in
                                          subscriptions(params).items() if t != SWITCH_TOPIC}}


def at_start(params: ControllerManagerParams, file: c.ControllersFile) -> list[str]:
    """The controllers active from the start: every one not listed in ``inactive``."""
    return [e.name for e in file.controllers if e.name not in params.inactive]


class ControllerManagerNode(StepNode):
    """ros2_control's controller manager with its standard controllers, as declared; run
    in the physics node's step (see the module)."""

    Params = ControllerManagerParams
    needs_world = True
    hardware_role = True  # folded into the physics node by the plan (plan/hardware_wiring.py)

    @classmethod
    def outputs(cls, params: ControllerManagerParams) -> dict[str, type]:
        """Every controller's published topics (``publications``)."""
        return publications(params)

    @classmethod
    def client_inputs(cls, params: ControllerManagerParams) -> dict[str, str]:
        """What ROS 2 clients feed an interactive run (``client_inputs``)."""
        return client_inputs(params)

    @classmethod
    def accepted_inputs(cls, params: ControllerManagerParams) -> set[str]:
        """What clients feed."""
        return set(cls.client_inputs(params))

    @classmethod
    def input_types(cls, params: ControllerManagerParams) -> dict[str, type]:
        """The switch topic's and the command topics' types (``subscriptions``)."""
        return subscriptions(params)

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
    def hosted_params(cls, params: ControllerManagerParams, name: str) -> BaseModel:
        """The physics node's ``controller_manager`` parameter that runs this manager in its
        step (nodes.ros2_control.hosted), named ``name``."""
        return HostedManagerParams(**{**params.model_dump(), "name": name})

    @classmethod
    def takes_hardware(cls, params: ControllerManagerParams) -> tuple[bool, bool]:
        """(whether its controllers command joints, whether they drive the base's wheels)."""
        return takes_hardware(params)

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

    def step(self, tick: Tick, inputs: dict[str, Any]) -> dict[str, Any]:
        """Never called: the plan folds the manager into the physics node's step."""
        raise RuntimeError("a controller manager runs in the physics node's step "
                           "(nodes.ros2_control.hosted), not as a node of its own")
