"""What list_hardware_interfaces and list_hardware_components answer for one controller
manager: the hardware of its robot (``nodes.ros2_control.hardware.hardware_info``, from the
compiled world as the node builds it), each command interface claimed or not by the active
controllers.

cosim simulates whatever hardware plugin the robot names with one MuJoCo system: one
component, active from the start, read and written at the manager's update rate. The
state interfaces are those the robot's ``<ros2_control>`` block declares
(``RobotModel.control``); a robot without one (an MJCF robot) has cosim's defaults: every
joint (its hinges and slides) has position, velocity and effort state interfaces (what its
``HardwareState`` carries). Every command interface is one a MuJoCo actuator realises (for
a URDF robot, every position, velocity or effort command interface the block declares: a
joint's one actuator switches to the mode an activated controller claims).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from controller_manager_msgs.msg import HardwareComponentState, HardwareInterface
from lifecycle_msgs.msg import State

from nodes.ros2_control.hardware import HardwareInfo, hardware_info
from nodes.ros2_control.interface import INTERFACES

PLUGIN = "cosim/MujocoSystem"
"""The plugin list_hardware_components names: cosim's MuJoCo system stands for the robot's."""


@dataclass(frozen=True)
class ManagerHardware:
    """A manager's hardware and its state interfaces: joint -> its interfaces (the block's,
    else position, velocity and effort of every hinge and slide: a floating base's free
    joint is no joint of a ``<ros2_control>`` block)."""

    info: HardwareInfo
    states: dict[str, tuple[str, ...]]


def manager_hardware(scenario, physics: str, robot: str = "") -> ManagerHardware:
    """The hardware the controller manager of robot ``robot`` ('' the unnamed one) drives,
    in the physics node ``physics`` that runs it, as that node finds it at setup (a robot
    that enters during the run: as it finds it when the robot enters)."""
    import mujoco

    from nodes.physics.world import load_model
    from runtime.build import node_config

    config = node_config(scenario, physics)
    found = [r for r in config.robots if r.name == robot] or list(config.robots[:1])
    layout = config.layout  # a robot that enters during the run is in the world with all
    model = load_model(config.world, layout if layout is None or robot in
                       layout.at_start.names else layout.everyone)
    info = hardware_info(model, found[0] if found else None,
                         config.params.controller_manager.command_joints)
    prefix = found[0].prefix if found else ""
    if info.states is not None:  # the block's
        return ManagerHardware(info, dict(info.states))
    kinds = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
    moving = {model.joint(j).name[len(prefix):] for j in range(model.njnt)
              if int(model.jnt_type[j]) in kinds and model.joint(j).name.startswith(prefix)}
    return ManagerHardware(info, {j: INTERFACES for j in info.joints if j in moving})


def interfaces(hardware: ManagerHardware, claimed: Iterable[str]
               ) -> tuple[list[HardwareInterface], list[HardwareInterface]]:
    """(command interfaces, state interfaces), sorted by name as the manager lists them."""
    taken = set(claimed)
    command = [HardwareInterface(name=n, data_type="double", is_available=True,
                                 is_claimed=n in taken)
               for n in sorted(hardware.info.command_interfaces())]
    state = [HardwareInterface(name=f"{j}/{i}", data_type="double", is_available=True)
             for j in sorted(hardware.states) for i in sorted(hardware.states[j])]
    return command, state


def component(hardware: ManagerHardware, name: str, claimed: Iterable[str], rate: int
              ) -> HardwareComponentState:
    """The one hardware component: cosim's MuJoCo system, active."""
    command, state = interfaces(hardware, claimed)
    return HardwareComponentState(
        name=name, type="system", is_async=False, rw_rate=rate, plugin_name=PLUGIN,
        state=State(id=State.PRIMARY_STATE_ACTIVE, label="active"),
        command_interfaces=command, state_interfaces=state)
