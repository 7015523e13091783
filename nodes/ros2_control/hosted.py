"""Controller managers hosted in the physics node's step, as mujoco_ros2_control's
``MujocoSystemInterface`` runs ros2_control inside the simulator's loop.

The plan folds a scenario's controller manager (a ``ros2_control`` node, or the one
``robots.controllers`` adds for every robot) into the physics node
(``plan.hardware_wiring``): physics' parameters carry it (``HostedManagerParams``) and
physics makes one ``HostedManagers``, which keeps a ``ControllerManager`` and a
``MujocoSystem`` per robot. At every activation of physics, after integrating up to the
tick, each manager reads its robot's joints straight from MjData into the controllers'
``HardwareState`` (``read``), takes the messages and requests of its topics, updates its
active controllers, and writes their commands straight into MjData's actuator controls
(``write``): a position, velocity or effort command to the joint's MuJoCo actuator, a diff
drive's wheel speeds to the wheels' velocity actuators (physics' own drive and its limiter
stand aside: one limiter, the controller's). A joint whose block declares several command
interfaces has one actuator whose mode (gains, bias, command range) is rewritten in the
model at the update a controller claiming another of them is activated
(``MujocoSystem.claim``), in the physics step at that tick, so every driver gives one
digest. The commands act over the next period, as ros2_control's read, update, write come
before the simulator's next step. No topic runs between controllers and hardware; the
controllers' own topics (``~/x`` under the controller's name, the switch topic) are
physics' inputs and outputs under the names a separate manager had, each robot's under its
namespace in a swarm.

The manager runs at the controllers file's ``update_rate``, physics' rate or physics' rate / n
for a whole n: it reads, updates and writes at every n-th activation of physics (ticks that
are multiples of its period), and its controllers' topics are published at those only (the
plan gives them that period: ``plan.schedule``); between updates the commands it wrote hold,
as a real controller's do between its cycles. A robot that enters the run gets its manager
at the tick it enters (its first update at the first of those ticks from then), after the
world is recompiled with it (``HostedManagers.rebind``: every other robot's system moves to
the new model's addresses, its controllers untouched); one that leaves takes its manager
with it.
"""

from __future__ import annotations

import math
from fractions import Fraction
from typing import Any

import mujoco
import numpy as np

from nodes.contract import quiet_message
from nodes.ros2_control.hardware import HardwareInfo, hardware_info, unservable
from nodes.ros2_control.interface import Fresh, JointStates
from nodes.ros2_control.manager import ControllerManager, resolve
from nodes.ros2_control.node import (  # noqa: F401 - the physics node's names for them
    SWITCH_TOPIC,
    SWITCH_TYPE,
    ControllerManagerParams,
    HostedManagerParams,
    at_start,
    client_inputs,
    message_type_name,
    publications,
    read,
    subscriptions,
    takes_hardware,
)
from nodes.ros2_control.requests import apply_request, request_lines
from plan.robots import namespaced
from plan.timeutil import NS_PER_S


def _index(addresses) -> slice | np.ndarray:
    """Addresses into an MjData array: a slice where they run one after another (a robot's
    joints mostly do; a slice reads cheaper than an index array), else the array."""
    index = np.asarray(addresses, dtype=np.int64)
    if len(index) and np.array_equal(index, np.arange(index[0], index[0] + len(index))):
        return slice(int(index[0]), int(index[0]) + len(index))
    return index


def set_mode(model, actuator: int, mode) -> None:
    """Make ``actuator`` of ``model`` what MuJoCo's shortcut for ``mode``'s interface makes it
    (``<position>``: gain kp, bias 0, -kp, -kv; ``<velocity>``: gain kv, bias 0, 0, -kv;
    ``<motor>``: gain 1, no bias), over ``mode.ctrlrange``."""
    gain, bias = model.actuator_gainprm[actuator], model.actuator_biasprm[actuator]
    gain[:] = 0.0
    bias[:] = 0.0
    if mode.interface == "position":
        gain[0], bias[1], bias[2] = mode.kp, -mode.kp, -mode.kv
        model.actuator_biastype[actuator] = mujoco.mjtBias.mjBIAS_AFFINE
    elif mode.interface == "velocity":
        gain[0], bias[2] = mode.kv, -mode.kv
        model.actuator_biastype[actuator] = mujoco.mjtBias.mjBIAS_AFFINE
    else:
        gain[0] = 1.0
        model.actuator_biastype[actuator] = mujoco.mjtBias.mjBIAS_NONE
    model.actuator_gaintype[actuator] = mujoco.mjtGain.mjGAIN_FIXED
    model.actuator_ctrllimited[actuator] = mode.ctrlrange is not None
    if mode.ctrlrange is not None:
        model.actuator_ctrlrange[actuator] = mode.ctrlrange


class MujocoSystem:
    """One robot's hardware over MjData: its joints' state read into ``state`` (the mapping
    the controllers are loaned, refreshed in place), command interfaces written to the
    actuators that realise them. A joint with several command interfaces has one actuator,
    in the mode of the interface claimed last (``claim``): ``mode``, joint -> interface."""

    def __init__(self, model, info: HardwareInfo, joints: list[str], qadr, dadr,
                 wheels: list[int] | None):
        self.info = info
        self.joints = joints
        self.state = JointStates(joints)
        self.mode = {c.name: c.interface for c in info.commands if c.modes}
        self.bind(model, qadr, dadr, wheels)

    def bind(self, model, qadr, dadr, wheels: list[int] | None) -> None:
        """The addresses of the joints (``qadr``, ``dadr``) and actuators in ``model``: a
        world recompiled with a robot in or out moves them (the robot's joints, actuators
        and the state its controllers were loaned stay what they were)."""
        info = self.info
        self.model = model
        self.qadr = _index(qadr)
        self.dadr = _index(dadr)
        self._viewed, self._views = None, None  # the MjData read last, views into it
        self._written, self._rows = None, []  # the commands written last: (actuator, value)
        self.actuator: dict[str, int] = {}  # 'joint/interface' -> actuator id
        self.modes: dict[str, Any] = {}  # 'joint/interface' -> the actuator's mode for it
        for c in info.commands:
            a = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, c.actuator)
            for interface in c.interfaces:
                self.actuator[f"{c.name}/{interface}"] = a
            for mode in c.modes:
                self.modes[f"{c.name}/{mode.interface}"] = mode
        for joint, interface in self.mode.items():  # a recompiled world: its modes again
            if interface != next(c.interface for c in info.commands if c.name == joint):
                key = f"{joint}/{interface}"
                set_mode(model, self.actuator[key], self.modes[key])
        if info.drive is not None and wheels is not None:
            self.actuator[f"{info.drive.left}/velocity"] = int(wheels[0])
            self.actuator[f"{info.drive.right}/velocity"] = int(wheels[1])
        # 'joint/interface' -> (min, max) the command is clamped to: the actuator's control
        # range, which the <ros2_control> block's min/max params narrow (descriptions.urdf)
        # (a mode's own range, for a joint with several command interfaces)
        self.limits: dict[str, tuple[float, float]] = {
            interface: (float(model.actuator_ctrlrange[a, 0]),
                        float(model.actuator_ctrlrange[a, 1]))
            for interface, a in self.actuator.items()
            if a >= 0 and model.actuator_ctrllimited[a] and interface not in self.modes}
        self.limits.update({interface: mode.ctrlrange for interface, mode in self.modes.items()
                            if mode.ctrlrange is not None})
        # 'joint/interface' -> (actuator, min, max), unbounded where no limits
        self.targets: dict[str, tuple[int, float, float]] = {
            interface: (a, *self.limits.get(interface, (-math.inf, math.inf)))
            for interface, a in self.actuator.items()}

    def read(self, data) -> None:
        """The joints' positions, velocities and actuator efforts, now (new readings: a
        controller may keep an earlier one)."""
        if data is not self._viewed:  # views of its joints' slices, kept while the MjData is
            self._viewed = data
            self._views = ((data.qpos[self.qadr], data.qvel[self.dadr],
                            data.qfrc_actuator[self.dadr])
                           if type(self.qadr) is slice and type(self.dadr) is slice else None)
        views = self._views
        if views is not None:
            q, v, e = views
            self.state.refresh(q.tolist(), v.tolist(), e.tolist())
        else:
            self.state.refresh(data.qpos[self.qadr].tolist(), data.qvel[self.dadr].tolist(),
                               data.qfrc_actuator[self.dadr].tolist())

    def start(self, data) -> None:
        """Before the first update: every position servo holds where its joint is (where
        the block's ``initial_value`` put it, ``nodes.physics.world.start_joints``), every
        other command is zero."""
        for interface, a in self.actuator.items():
            joint, _, kind = interface.rpartition("/")
            if self.mode.get(joint, kind) != kind:
                continue  # the actuator is in another of the joint's modes
            data.ctrl[a] = self._hold(joint, kind)

    def _hold(self, joint: str, kind: str) -> float:
        """What an actuator commanded through interface ``kind`` holds before a controller
        commands it: a position where the joint is, a velocity or effort 0."""
        reading = self.state.get(joint)
        return reading.position if kind == "position" and reading else 0.0

    def claim(self, data, claimed) -> None:
        """Switch each joint with several command interfaces that a controller claims
        through another interface than its actuator's mode to that interface's mode
        (``claimed``: the active controllers' command interfaces, just after a switch), as
        ros2_control's ``perform_command_mode_switch``; until the controller commands, the
        actuator holds: a position mode where the joint is, a velocity or effort mode 0."""
        if not self.modes:
            return
        for interface in claimed:
            mode = self.modes.get(interface)
            if mode is None:
                continue
            joint = interface.rpartition("/")[0]
            if self.mode[joint] == mode.interface:
                continue
            self.mode[joint] = mode.interface
            a = self.actuator[interface]
            set_mode(self.model, a, mode)
            data.ctrl[a] = self._hold(joint, mode.interface)

    def write(self, data, commands: dict[str, float]) -> None:
        """The controllers' commands into the actuators (an interface no controller
        commands keeps its last value), each clamped to its command limits (the
        ``<ros2_control>`` block's ``min``/``max`` within the joint's ``<limit>``), as
        Jazzy's controller manager saturates a command with ``enforce_command_limits: true``
        (the value range only; it also bounds a position step by the velocity limit, which
        cosim does not)."""
        if commands is not self._written:  # a mapping given again is the same commands
            targets = self.targets
            self._written, self._rows = commands, [
                (target[0], min(max(value, target[1]), target[2]))
                for interface, value in commands.items()
                if (target := targets.get(interface)) is not None]
        ctrl = data.ctrl
        for a, value in self._rows:
            ctrl[a] = value


class RobotManager:
    """One robot's controller manager: its controllers, requests and hardware."""

    def __init__(self, params: HostedManagerParams, system: MujocoSystem, robot: str,
                 namespace: str, held: frozenset[str], note):
        """``robot``: its name (its metrics' prefix), ``namespace``: its topics' ('' the
        root); ``held``: physics' inputs fed by the external node."""
        self.params = params
        self.file = read(params)
        self.system = system
        self.robot = robot
        self.note = note
        self.manager = ControllerManager(self.file, namespace)
        self.manager.unservable = unservable(self.manager.controllers, system.info)
        self.declared = publications(params)
        # topic -> (its controller, the controller's own name for it)
        self.owner = {resolve(name, t): (name, t) for name, ctrl in
                      self.manager.controllers.items() if ctrl is not None
                      for t in ctrl.publications()}
        self.inputs = list(subscriptions(params))
        self.graph = {t: namespaced(namespace, t) for t in [*self.inputs, *self.declared]}
        self.held = frozenset(t for t in self.inputs if self.graph[t] in held)
        self.routes = [(t, self.graph[t]) for t in self.inputs]  # (own, physics' name)
        self.same_names = all(own == graph for own, graph in self.routes)  # at the root
        self.outputs = [(t, self.graph[t], cls) for t, cls in self.declared.items()]
        self.empty: dict[str, Any] = {}  # topic -> what it carries while not published
        self.fresh = Fresh()
        self.request, self.refused = 0, []  # the newest request handled; refused this tick
        self.first = True
        for text in self.manager.notes():
            note(text)
        for name, why in self.manager.unservable.items():
            note(f"{name}: {why}: it is loaded, and its activation is refused.")

    def step(self, time_ns: int, period_ns, data, inputs: dict[str, Any], out: dict) -> None:
        """Read, update, write; what the controllers publish into ``out`` (physics' names)."""
        system = self.system
        system.read(data)
        # the manager looks up only its own topics: physics' inputs will do where they are
        # named alike (a robot at the root)
        mine = inputs if self.same_names else {
            t: msg for t, graph in self.routes if (msg := inputs.get(graph)) is not None}
        commands: dict[str, float] = {}
        if self.first:
            system.start(data)
            commands.update(self.manager.activate(at_start(self.params, self.file),
                                                  system.state).commands)
            system.claim(data, self.manager.claimed())
            self.first = False
        switch = mine.get(SWITCH_TOPIC)
        if switch is not None:
            commands.update(self._switch(switch))
            system.claim(data, self.manager.claimed())
        elif self.refused:
            self.refused = []
        done = self.manager.update(time_ns, period_ns, mine, self.held)
        for text in done.notes:
            self.note(text)
        if commands:
            commands.update(done.commands)
        else:
            commands = done.commands
        system.write(data, commands)
        # lockstep wants one message per declared topic and activation: an inactive
        # controller's topics carry an empty message of their type, nothing of the controller
        # (made once, and its bytes once: the runtime only stamps it with the tick's time),
        # which the runtime leaves out where no node of the run takes the topic
        published = done.published
        for topic, graph, cls in self.outputs:
            msg = published.get(topic)
            if msg is None:
                msg = self.empty.get(topic)
                if msg is None:
                    name, own = self.owner[topic]
                    ctrl = self.manager.controllers.get(name)
                    msg = self.empty[topic] = (cls() if ctrl is None
                                               else ctrl.empty_message(own))
                quiet_message(msg)
            out[graph] = msg

    def _switch(self, msg) -> dict[str, float]:
        """The requests of the switch topic (``nodes.ros2_control.requests``) not handled
        before: a request with an id once, one without when the message is new (those
        refused at this tick: ``refused``)."""
        self.refused = []
        new = self.fresh(SWITCH_TOPIC, msg)
        commands: dict[str, float] = {}
        for rid, body in request_lines(msg.data):
            if (rid is None and not new) or (rid is not None and rid <= self.request):
                continue
            self.request = max(self.request, rid or 0)
            done, why = apply_request(self.manager, body, self.system.state)
            commands.update(done)
            if why:
                self.note(why if rid is None else f"{why} (request {rid})")
                if rid is not None:
                    self.refused.append(rid)
        return commands

    def metrics(self, prefix: str = "") -> dict[str, float]:
        """Each controller's state (``active:<name>`` 1 or 0; ``state:<name>`` 0 unloaded,
        1 unconfigured, 2 inactive, 3 active), each trajectory controller's newest goal
        (number, state, result code, the joint that broke a tolerance), the newest request
        handled (``request``) and those refused at this tick (``refused:<id>`` 1); every key
        after ``prefix``."""
        out = self.manager.metrics(prefix)
        out[prefix + "request"] = float(self.request)
        for r in self.refused:
            out[f"{prefix}refused:{r}"] = 1.0
        return out


def manager_period_ns(params: HostedManagerParams, physics_period_ns):
    """The period of the manager's updates: 1 s / its ``update_rate``, exact (an int where
    whole; physics' own period, as given, where they are equal)."""
    period = Fraction(NS_PER_S, read(params).update_rate)
    if period == physics_period_ns:
        return physics_period_ns
    return int(period) if period.denominator == 1 else period


def metric_prefix(name: str, robot: str) -> str:
    """Where a hosted manager's metrics go in physics': 'controller_manager/' for the
    unnamed robot, 'robot_2/controller_manager/' in a swarm."""
    return f"{robot}/{name}/" if robot else f"{name}/"


def hardware_joints(model, robot, qadr) -> list[str]:
    """The names the controllers know the joints at qpos addresses ``qadr`` by: their MuJoCo
    names less the robot's MuJoCo prefix ('robot_0/left_wheel_joint' -> 'left_wheel_joint'),
    whatever namespace its frames are in (``Rig.state_names`` are frames: 'alpha/...')."""
    prefix = robot.prefix or ""
    names = {int(model.jnt_qposadr[j]): model.joint(j).name for j in range(model.njnt)}
    return [names[int(q)].removeprefix(prefix) for q in qadr]


class HostedManagers:
    """Every robot's controller manager in the physics step (the module says how)."""

    def __init__(self, params: HostedManagerParams, model, rigs, robots, held: frozenset[str],
                 note):
        """``rigs``: physics' robots (nodes.physics.swarm.Rig), ``robots``: their models."""
        self.params, self.held, self.note = params, held, note
        self.managers: list[RobotManager] = []
        self.published: frozenset[str] = frozenset()
        joints, base = takes_hardware(params)
        self.commands_joints = joints
        self.drives_base = base
        self.rebind(model, rigs, robots)

    def rebind(self, model, rigs, robots) -> None:
        """Follow the world ``model`` with the robots ``rigs`` now (first, and after every
        recompile that brought a robot in or took one out): each robot already there keeps
        its manager (its controllers and their state) over its joints' and actuators' new
        addresses; a robot that entered gets its manager, which activates its controllers
        at its first update (this tick); one that left takes its manager with it."""
        had = {m.robot: m for m in self.managers}
        self.managers = []
        for rig, robot in zip(rigs, robots, strict=True):
            wheels = rig.wheel_act if rig.drive is not None else None
            manager = had.get(rig.name)
            if manager is not None:
                manager.system.bind(model, rig.state_q, rig.state_v, wheels)
                self.managers.append(manager)
                continue
            info = hardware_info(model, robot, self.params.command_joints)
            joints = hardware_joints(model, robot, rig.state_q)
            system = MujocoSystem(model, info, joints, rig.state_q, rig.state_v, wheels)
            namespace = getattr(robot, "namespace", rig.name)  # '' for a robot at the root
            self.managers.append(RobotManager(self.params, system, rig.name, namespace,
                                              self.held, self.note))
        # every topic the managers publish (physics' graph names): a broadcaster's
        # /joint_states replaces physics' own, which physics then does not build (those of
        # a robot that left stay in: no robot takes its name again)
        self.published = self.published | frozenset(
            m.graph[t] for m in self.managers for t in m.declared)

    def step(self, time_ns: int, period_ns, data, inputs: dict[str, Any], out: dict) -> None:
        """One update of every robot's manager, at the state physics publishes at the tick;
        their topics into ``out`` (over physics' own of the same name: a joint state
        broadcaster's /joint_states is the robot's)."""
        for manager in self.managers:
            manager.step(time_ns, period_ns, data, inputs, out)

    def metrics(self) -> dict[str, float]:
        """Each manager's metrics under ``metric_prefix``."""
        if len(self.managers) == 1:
            manager = self.managers[0]
            return manager.metrics(metric_prefix(self.params.name, manager.robot))
        out: dict[str, float] = {}
        for manager in self.managers:
            out.update(manager.metrics(metric_prefix(self.params.name, manager.robot)))
        return out
