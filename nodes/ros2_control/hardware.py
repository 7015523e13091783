"""cosim's hardware for the controller manager: which joints and interfaces the robot
exports (``HardwareInfo``, from the robot model and its MuJoCo actuators: each command
interface is one a joint's actuator realises, a mobile base's wheels take velocities). The
physics step reads and writes it over MjData (``nodes.ros2_control.hosted.MujocoSystem``).

A joint whose ``<ros2_control>`` block declares several command interfaces (UR's position
and velocity) exports them all over its one actuator, whose mode the hardware switches to
the interface an activated controller claims (``ActuatedJoint.modes``), as ros2_control's
``perform_command_mode_switch`` does; one command interface of a joint is claimed at a
time (two active controllers claiming the joint's position and velocity are refused, as
upstream's hardware rejects the switch in ``prepare_command_mode_switch``).

A command interface a controller claims and MuJoCo cannot realise (a velocity command for
a joint whose actuator is a position servo, a joint no actuator drives), or a state
interface the robot's ``<ros2_control>`` block does not declare (a robot with one), is a
problem naming the joint and interface: found when the scenario loads for a controller
active from the start, its activation refused for one loaded inactive, as upstream's.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco

from nodes.ros2_control.interface import Claim

MODES = ("position", "velocity", "effort")  # the command interfaces an actuator switches to


@dataclass(frozen=True)
class CommandJoint:
    """A joint physics takes commands for: its name, the interface its MuJoCo actuator
    realises as built (None: none of position, velocity, effort), the actuator, and the
    modes it can be switched to (``descriptions.robot_model.ActuatorMode``, the built one
    first; (): only ``interface``)."""

    name: str
    interface: str | None
    actuator: str
    modes: tuple = ()

    @property
    def interfaces(self) -> tuple[str, ...]:
        """Every command interface it can be commanded by."""
        if self.modes:
            return tuple(m.interface for m in self.modes)
        return (self.interface,) if self.interface else ()


def joint_mode_conflict(claims: list[tuple[str, tuple[str, ...]]]) -> tuple[str, ...] | None:
    """The first joint two command interfaces (position, velocity, effort) of ``claims``
    ((controller, command interfaces), in order) command at once: (joint, interface,
    its controller, other interface, its controller), or None."""
    seen: dict[str, tuple[str, str]] = {}
    for name, command in claims:
        for interface in command:
            joint, _, kind = interface.rpartition("/")
            if kind not in MODES:
                continue
            other = seen.setdefault(joint, (interface, name))
            if other[0] != interface:
                return joint, other[0], other[1], interface, name
    return None


@dataclass(frozen=True)
class DriveWheels:
    """A differential drive's wheels (velocity commands to their velocity actuators)."""

    left: str
    right: str
    radius: float
    separation: float


@dataclass(frozen=True)
class HardwareInfo:
    """The robot's joints (names as its controllers file gives them), the joints physics
    takes commands for in /joint_commands order, its drive's wheels, and the state
    interfaces its ``<ros2_control>`` block declares (joint -> interfaces; None: the robot
    has no block, and every joint reads position, velocity and effort)."""

    joints: tuple[str, ...]
    commands: tuple[CommandJoint, ...]
    drive: DriveWheels | None = None
    states: dict[str, tuple[str, ...]] | None = field(default=None, hash=False)

    def command_interfaces(self) -> set[str]:
        """Every command interface the hardware exports (``joint/interface``)."""
        out = {f"{c.name}/{i}" for c in self.commands for i in c.interfaces}
        if self.drive is not None:
            out |= {f"{self.drive.left}/velocity", f"{self.drive.right}/velocity"}
        return out

    def problems(self, claim: Claim) -> list[tuple[str, str]]:
        """Why the hardware cannot give a controller what it claims: (problem, accepted)."""
        exported = self.command_interfaces()
        out = []
        for name in [*claim.command, *claim.state]:
            joint = name.rpartition("/")[0]
            if joint not in self.joints:
                out.append((f"joint {joint!r} is not in the world.", "joints of the robot: "
                            + ", ".join(sorted(j for j in self.joints if j)) + "."))
        if out:
            return out[:1]
        for name in claim.command:
            if name not in exported:
                return [self._missing(name)]
        both = joint_mode_conflict([("", claim.command)])
        if both is not None:
            return [(f"joint {both[0]!r}: the claim has {both[1]} and {both[3]}: its actuator "
                     "takes one command interface at a time.", "one command interface per "
                     "joint.")]
        if self.states is not None and not claim.every_state:
            for name in claim.state:
                joint, _, interface = name.rpartition("/")
                if interface not in self.states.get(joint, ()):
                    return [self._undeclared(joint, interface)]
        return []

    def _undeclared(self, joint: str, interface: str) -> tuple[str, str]:
        have = ", ".join(self.states.get(joint, ())) or "none"
        return (f"joint {joint!r} has no {interface} state interface: the robot's "
                f"<ros2_control> block does not declare it (its state interfaces: {have}).",
                f"a controller claiming state interfaces the block declares, or <state_"
                f"interface name=\"{interface}\"/> on joint {joint!r} in the robot's "
                "<ros2_control> block.")

    def _missing(self, name: str) -> tuple[str, str]:
        joint, _, interface = name.rpartition("/")
        have = next((c for c in self.commands if c.name == joint), None)
        if have is not None and have.interfaces:
            why = (f"its MuJoCo actuator {have.actuator!r} takes "
                   f"{' or '.join(have.interfaces)} commands")
        elif have is not None:
            why = (f"its MuJoCo actuator {have.actuator!r} is no position, velocity or motor "
                   "actuator")
        elif self.drive is not None and joint in (self.drive.left, self.drive.right):
            why = "a drive wheel takes velocity commands"
        else:
            why = "physics takes no command for it (no actuator of the robot's commanded joints)"
        served = ", ".join(sorted(self.command_interfaces())) or "none"
        return (f"joint {joint!r} has no {interface} command interface in cosim's hardware: "
                f"{why}.", f"a controller claiming an interface the hardware has ({served}); "
                f"for {interface} on {joint!r}, a {interface} actuator on the joint (a URDF "
                f"robot: <command_interface name=\"{interface}\"/> in its <ros2_control> "
                "block).")


def actuator_interface(model, actuator: int) -> str | None:
    """The command interface a MuJoCo actuator realises: ``position`` (a servo: affine bias
    on the position), ``velocity`` (affine bias on the velocity only), ``effort`` (a motor:
    no bias), else None."""
    if model.actuator_trntype[actuator] != mujoco.mjtTrn.mjTRN_JOINT:
        return None
    bias = model.actuator_biastype[actuator]
    if bias == mujoco.mjtBias.mjBIAS_NONE:
        return "effort"
    if bias == mujoco.mjtBias.mjBIAS_AFFINE:
        if model.actuator_biasprm[actuator, 1] != 0.0:
            return "position"
        if model.actuator_biasprm[actuator, 2] != 0.0:
            return "velocity"
    return None


def hardware_info(model, robot, command_joints: list[str] | None = None) -> HardwareInfo:
    """The hardware of ``robot`` (a RobotModel, or None) in the compiled world ``model``: its
    joints, the joints physics takes commands for (``command_joints`` in that order, else the
    robot's commanded joints, else the world's position servos), the interface each one's
    actuator realises, its drive's wheels."""
    prefix = robot.prefix if robot is not None else ""

    def local(name: str) -> str:
        return name[len(prefix):] if prefix and name.startswith(prefix) else name

    names = [model.joint(j).name for j in range(model.njnt)]
    joints = tuple(local(n) for n in names if n and (not prefix or n.startswith(prefix)))
    actuators = {}  # joint -> its first joint actuator
    for a in range(model.nu):
        if model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT:
            actuators.setdefault(names[int(model.actuator_trnid[a, 0])], a)
    if command_joints is not None:
        wanted = list(command_joints)
    elif robot is not None:
        wanted = [local(a.joint) for a in robot.actuated]
    else:  # a node made outside a scenario, no robot model: the world's position servos
        wanted = [names[int(model.actuator_trnid[a, 0])] for a in range(model.nu)
                  if actuator_interface(model, a) == "position"]
    modes = {local(a.joint): a.modes for a in robot.actuated} if robot is not None else {}
    commands = []
    for joint in wanted:
        a = actuators.get(prefix + joint)
        if a is None:
            continue
        interface = actuator_interface(model, a)
        switchable = modes.get(joint, ())
        if switchable and switchable[0].interface != interface:
            switchable = ()  # not the actuator the description built
        commands.append(CommandJoint(joint, interface, model.actuator(a).name, switchable))
    drive = None
    if robot is not None and robot.drive is not None:
        d = robot.drive
        drive = DriveWheels(local(d.left_joint), local(d.right_joint), d.wheel_radius,
                            d.wheel_separation)
    block = robot.control if robot is not None else ()
    states = {local(c.joint): c.states for c in block if c.states} if block else None
    return HardwareInfo(joints, tuple(commands), drive, states)


def unservable(controllers, info: HardwareInfo) -> dict[str, str]:
    """controller -> the first interface of its claim the hardware lacks, said (only those
    the hardware cannot serve; ``controllers``: name -> controller or None)."""
    out = {}
    for name, ctrl in controllers.items():
        problems = info.problems(ctrl.claim()) if ctrl is not None else []
        if problems:
            out[name] = problems[0][0].rstrip(".")
    return out
