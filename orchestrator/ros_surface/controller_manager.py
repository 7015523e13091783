"""The controller manager's face of an interactive run whose robots have a controller
manager (run in the physics node's step: nodes.ros2_control.hosted): the
services of controller_manager_msgs under ``/controller_manager/`` (``list_controllers``
with claimed interfaces, ``list_controller_types``, ``list_hardware_interfaces``,
``list_hardware_components``, ``switch_controller`` with upstream's strictness,
``load_controller``, ``unload_controller``, ``configure_controller``) and the actions
controllers offer (a trajectory controller's ``~/follow_joint_trajectory``, a parallel
gripper's ``~/gripper_cmd``: their faces in ``controller_actions``). A robot's manager in a
swarm (``for_each: robot``) serves them under the robot's namespace, as a namespaced
ros2_control_node does: ``/robot_2/controller_manager/list_controllers``,
``/robot_2/joint_trajectory_controller/follow_joint_trajectory``.

What changes the run (a goal, a cancel, a switch) is put into the run's external arrivals and
enters the physics node, where the manager runs, at its next activation, at a tick boundary,
recorded like any message; the answers follow physics' metrics of the manager
(``controller_manager/...``, ``ROBOT/controller_manager/...`` in a swarm) at the ticks the
master decides (its controllers' states, each trajectory controller's newest goal: number,
state, result code).

A robot that enters or leaves the run (``events:``, SpawnEntity, DeleteEntity) has its
manager only while it is in the run (physics has its metrics then): before it enters and
after it leaves, its manager lists no controllers and no hardware, refuses every switch,
load, unload, configure and goal, saying so, and a request or goal that was waiting when
the robot left is answered as failed.
"""

from __future__ import annotations

import logging
import threading
from collections import deque

from controller_manager_msgs.msg import ControllerState
from controller_manager_msgs.srv import (
    ConfigureController,
    ListControllers,
    ListControllerTypes,
    ListHardwareComponents,
    ListHardwareInterfaces,
    LoadController,
    SwitchController,
    UnloadController,
)
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.qos import QoSProfile
from std_msgs.msg import String

from nodes.ros2_control.controllers.joint_trajectory_controller import GOAL
from nodes.ros2_control.goals import ACTIVE, CANCEL_ID, DEACTIVATED, GOAL_ID
from nodes.ros2_control.hardware import unservable
from nodes.ros2_control.hosted import metric_prefix
from nodes.ros2_control.manager import STATE_CODES, lifecycle_problem, load, resolve
from nodes.ros2_control.node import SWITCH_TOPIC, at_start, read
from nodes.ros2_control.registry import BASE_CLASS, served_types
from nodes.ros2_control.switching import STRICTNESS, plan_switch
from orchestrator.ros_surface import controller_hardware as hardware
from orchestrator.ros_surface.controller_actions import FACES
from orchestrator.ros_surface.simcontrol import PAUSED, RunControl
from plan.robots import namespace_in, namespaced
from plan.scenario import EXTERNAL_NAME, Scenario
from runtime.arrivals import Arrivals

WAIT_S = 0.1
STATE_NAMES = {code: name for name, code in STATE_CODES.items()}
LIFECYCLE = {"load": (LoadController, "unconfigured"),
             "unload": (UnloadController, "unloaded"),
             "configure": (ConfigureController, "inactive")}
log = logging.getLogger("cosim")


class ControllerManagerServer:
    """list/switch controllers and the trajectory controllers' actions of one node."""

    def __init__(self, node, group, control: RunControl, arrivals: Arrivals, plan,
                 answering=lambda handler: handler, scenario: Scenario | None = None,
                 robot: str = "", namespace: str = ""):
        """``plan``: the physics node's, which runs the manager of robot ``robot`` (its
        metrics' prefix; '' the unnamed robot), whose topics are under ``namespace`` ('' the
        root). ``answering`` wraps the handlers that wait on the run (switch_controller, a
        goal's execution) so that the end of the run waits for their answers before the
        servers go (``SimServices.close``): a goal open when the run ends gets its result.
        ``scenario``: where the hardware lists find the robot's hardware."""
        self.control = control
        self.arrivals = arrivals
        self.physics = plan.name
        self.robot = robot
        self.scenario = scenario
        params = plan.params.controller_manager
        self.prefix = metric_prefix(params.name, robot)
        self.file = read(params)
        # the manager's own topics (its robot's, without the namespace) -> graph names
        self.topics = {_local(inp.topic, namespace): inp.graph_topic for inp in plan.inputs
                       if inp.producer == EXTERNAL_NAME and _local(inp.topic, namespace)}
        # a robot's manager lives under its namespace: '/robot_2' ('' for the scenario's own)
        self.ns = self.topics[SWITCH_TOPIC][:-len(SWITCH_TOPIC)]
        prefix = f"{self.ns}/controller_manager/"
        self.controllers = load(self.file)  # what each claims and offers, from its parameters
        starting = at_start(params, self.file)
        self.states = {name: ("unconfigured" if ctrl is None else "active" if name in starting
                              else "inactive") for name, ctrl in self.controllers.items()}
        self._hardware = None
        layout = scenario.robots if scenario is not None else None
        # whether the robot is in the run (as of the newest tick seen): those of the start
        self.present = layout is None or not robot or robot in layout.at_start.names
        self._cond = threading.Condition()
        self._reports: deque[tuple[int, dict[str, float]]] = deque(maxlen=4096)
        self._seq = 0
        self._latest: dict[str, object] = {}
        self._sent = 0  # goals and cancels put, which name them
        self._requests = 0  # switch, load, unload, configure requests put, which name them
        # id of a goal request -> its number (cosim-goal-<n>, the controller's goal_seq) and
        # the newest report when it was put
        self._seq_of: dict[int, tuple[int, int]] = {}
        self._never_entered: dict[int, str] = {}  # id of a goal request -> why
        node.create_service(ListControllers, prefix + "list_controllers", self._list,
                            callback_group=group)
        node.create_service(ListControllerTypes, prefix + "list_controller_types", self._types,
                            callback_group=group)
        node.create_service(ListHardwareInterfaces, prefix + "list_hardware_interfaces",
                            self._hardware_interfaces, callback_group=group)
        node.create_service(ListHardwareComponents, prefix + "list_hardware_components",
                            self._hardware_components, callback_group=group)
        node.create_service(SwitchController, prefix + "switch_controller",
                            answering(self._switch), callback_group=group)
        for verb, (srv, _) in LIFECYCLE.items():
            node.create_service(srv, f"{prefix}{verb}_controller",
                                answering(self._lifecycle(verb)), callback_group=group)
        self.actions = []
        self._active_handles: dict[str, object] = {}  # controller -> its executing goal
        self.faces = {}  # controller -> the face of the action it offers
        for name, ctrl in self.controllers.items():
            for action_name, action in (ctrl.actions() if ctrl is not None else {}).items():
                face = FACES.get(action)
                if face is None or resolve(name, GOAL) not in self.topics:
                    continue
                self.faces[name] = face
                if face.feedback_topic is not None:
                    own = resolve(name, face.feedback_topic)
                    topic = plan.output_names.get(namespaced(namespace, own),
                                                  self.ns + own)
                    node.create_subscription(
                        ctrl.publications()[face.feedback_topic], topic, self._feedback(name),
                        QoSProfile(depth=10), callback_group=group)
                self.actions.append(ActionServer(
                    node, action, self.ns + resolve(name, action_name),
                    answering(self._executor(name)), callback_group=group,
                    goal_callback=self._goal_callback(name),
                    cancel_callback=self._cancel_callback(name)))
        control.observers.append(self._observe)

    def _observe(self, tick: int, reports: dict) -> None:
        done = reports.get(self.physics)
        if done is None:
            return
        n = len(self.prefix)
        mine = {k[n:]: v for k, v in done.metrics.items() if k.startswith(self.prefix)}
        with self._cond:
            self.present = bool(mine)  # its manager reports while the robot is in the run
            self._seq += 1
            self._reports.append((self._seq, mine))
            for name in self.controllers:
                code = mine.get(f"state:{name}")
                if code is None:
                    continue
                if code == STATE_CODES["unloaded"]:
                    self.states.pop(name, None)
                else:
                    self.states[name] = STATE_NAMES[code]
            self._cond.notify_all()

    def active(self, name: str) -> bool:
        """Whether controller ``name`` is active (as of the newest tick seen)."""
        return self.states.get(name) == "active"

    def _claimed(self) -> list[str]:
        return [i for n, c in self.controllers.items() if c is not None and self.active(n)
                for i in c.claim().command]

    def _absent(self) -> str | None:
        """Why the manager cannot act now (its robot is not in the run), or None."""
        if self.present:
            return None
        return (f"robot {self.robot!r} is not in the run at {self.control.at()} (its "
                "controller manager runs only while the robot is in the run)")

    def _list(self, request, response):
        with self._cond:
            states = dict(self.states) if self.present else {}
        for entry in self.file.controllers:
            if entry.name not in states:  # unloaded
                continue
            ctrl = self.controllers[entry.name]
            state = ControllerState(name=entry.name, type=entry.type, state=states[entry.name],
                                    update_rate=self.file.update_rate)
            if ctrl is not None:
                claim = ctrl.claim()
                state.required_command_interfaces = list(claim.command)
                state.required_state_interfaces = list(claim.state)
                if states[entry.name] == "active":  # an inactive controller claims nothing
                    state.claimed_interfaces = list(claim.command)
            response.controller.append(state)
        return response

    def hardware(self):
        """The robot's hardware (read from the world once, at the first question)."""
        if self._hardware is None:
            self._hardware = hardware.manager_hardware(self.scenario, self.physics,
                                                       self.robot)
        return self._hardware

    def _hardware_interfaces(self, request, response):
        with self._cond:
            claimed = self._claimed()
            if not self.present:
                return response
        response.command_interfaces, response.state_interfaces = hardware.interfaces(
            self.hardware(), claimed)
        return response

    def _hardware_components(self, request, response):
        with self._cond:
            claimed = self._claimed()
            if not self.present:
                return response
        name = self.ns.strip("/") or "cosim"
        response.component = [hardware.component(self.hardware(), f"{name}_mujoco_system",
                                                  claimed, self.file.update_rate)]
        return response

    def _types(self, request, response):
        response.types = served_types()
        response.base_classes = [BASE_CLASS] * len(response.types)
        return response

    def _switch(self, request, response):
        """As upstream's: the strictness decides what is switched; the switch enters at the
        next tick (activate_asap or not: every switch happens at the update it enters, so
        the timeout is not waited on)."""
        with self._cond:
            states = dict(self.states)
            absent = self._absent()
        if absent:
            log.warning("%s/controller_manager/switch_controller refused: %s", self.ns, absent)
            response.ok, response.message = False, absent
            return response
        claims = {n: c.claim().command for n, c in self.controllers.items() if c is not None}
        unrunnable = {n: f"its type {self.file.named(n).type!r} is one cosim cannot run (it "
                      "is loaded and stays inactive)" for n, c in self.controllers.items()
                      if c is None}
        unrunnable.update({n: f"{why} (it is loaded and stays inactive)" for n, why in
                           unservable(self.controllers, self.hardware().info).items()})
        done = plan_switch(states, claims, list(request.activate_controllers),
                           list(request.deactivate_controllers), request.strictness, unrunnable)
        log.info("%sswitch_controller (%s) at %s: %s", self.ns + "/controller_manager/",
                 STRICTNESS.get(request.strictness, "default: BEST_EFFORT"), self.control.at(),
                 done.message.replace("\n", "; "))
        response.ok, response.message = done.ok, done.message
        if not done.ok or not (done.activate or done.deactivate):
            return response
        body = " ".join([*(f"-{n}" for n in done.deactivate),
                         *(f"+{n}" for n in done.activate)])
        return self._enter(body, response, "switch")

    def _lifecycle(self, verb: str):
        """load_controller, unload_controller or configure_controller, as upstream's."""

        def handle(request, response):
            with self._cond:
                states = dict(self.states)
                absent = self._absent()
            problem = absent or lifecycle_problem(self.file, self.controllers, states, verb,
                                                  request.name)
            if problem:
                log.warning("%s/controller_manager/%s_controller refused at %s: %s", self.ns,
                            verb, self.control.at(), problem)
                response.ok = False
                return response
            return self._enter(f"{verb}:{request.name}", response, f"{verb} of {request.name}")
        return handle

    def _enter(self, body: str, response, what: str):
        """Put request ``body`` into the run with its id (requests of one tick enter together,
        one a line: ``nodes.ros2_control.requests``) and answer as the node reports it: done
        or refused (a paused run: at once, saying when it enters)."""
        with self._cond:
            seen = self._seq
            self._requests += 1
            rid = self._requests
            self.arrivals.put(self.topics[SWITCH_TOPIC], String(data=f"#{rid} {body}"),
                              merge=lambda waiting, msg: String(data=f"{waiting.data}\n"
                                                                 f"{msg.data}"))
        if self.control.state == PAUSED:  # it cannot wait for a tick nobody asks for
            response.ok = True
            if hasattr(response, "message"):
                response.message += f"\n(the {what} enters at {self.control.at()}: the run " \
                    "is paused)"
            return response
        while True:
            ended = self.control.ended
            with self._cond:
                if self._seq == seen:
                    self._cond.wait(WAIT_S)
                fresh = [m for s, m in self._reports if s > seen]
            handled = next((m for m in fresh if m.get("request", 0.0) >= rid or not m), None)
            if handled is not None and not handled:  # no manager: its robot left the run
                response.ok = False
                if hasattr(response, "message"):
                    response.message = f"the robot left the run before the {what} entered"
                return response
            if handled is not None:
                response.ok = f"refused:{rid}" not in handled
                if not response.ok and hasattr(response, "message"):
                    response.message = (f"the controller manager refused the {what} when it "
                                        "entered (its reason is in the run's notes)")
                return response
            if ended is not None:
                response.ok = False
                if hasattr(response, "message"):
                    response.message = f"the run ended before the {what}: {ended}"
                return response

    def _goal_callback(self, name: str):
        face = self.faces[name]
        label = face.action.__name__

        def on_goal(request) -> GoalResponse:
            with self._cond:
                if (absent := self._absent()) is not None:
                    log.warning("%s: goal for %s rejected: %s", label, name, absent)
                    return GoalResponse.REJECT
                if not self.active(name):  # as upstream: nothing would ever answer it
                    log.warning("%s: goal for %s rejected at %s: the controller is not "
                                "running (activate it with /controller_manager/"
                                "switch_controller)", label, name, self.control.at())
                    return GoalResponse.REJECT
                if (why := face.refuse(request)) is not None:
                    log.warning("%s: goal for %s rejected at %s: %s", label, name,
                                self.control.at(), why)
                    return GoalResponse.REJECT
                self._sent += 1
                replaced = self.arrivals.put(self.topics[resolve(name, GOAL)],
                                             face.entering(request, f"{GOAL_ID}{self._sent}"))
                previous = self._latest.get(name)
                if replaced is not None and previous and face.is_goal(replaced):
                    self._never_entered[id(previous)] = "replaced by a newer goal before it " \
                        "entered the run (both arrived within one tick)"
                self._seq_of[id(request)] = (self._sent, self._seq)
                self._latest[name] = request
                number = self._sent
            log.info("%s: goal %d for %s from %s", label, number, name, self.control.at())
            return GoalResponse.ACCEPT
        return on_goal

    def _cancel_callback(self, name: str):
        face = self.faces[name]

        def on_cancel(handle) -> CancelResponse:
            with self._cond:
                if self._latest.get(name) is handle.request:
                    self._sent += 1
                    replaced = self.arrivals.put(self.topics[resolve(name, GOAL)],
                                                 face.cancel(f"{CANCEL_ID}{self._sent}"))
                    if replaced is not None and face.is_goal(replaced):
                        self._never_entered[id(handle.request)] = "cancelled before it " \
                            "entered the run"
            return CancelResponse.ACCEPT
        return on_cancel

    def _feedback(self, name: str):
        """Feedback of the executing goal from the controller's state topic (it tells the
        client how the motion goes; nothing of it enters the run)."""
        face = self.faces[name]

        def forward(state) -> None:
            handle = self._active_handles.get(name)
            if handle is None or not handle.is_active:
                return
            handle.publish_feedback(face.feedback(state))
        return forward

    def _executor(self, name: str):
        face = self.faces[name]
        label = face.action.__name__

        def finish(handle, ending):
            log.info("%s: %s %s", label, ending.how, ending.text)
            getattr(handle, ending.how)()
            return ending.result

        def execute(handle):
            self._active_handles[name] = handle
            with self._cond:
                mine, put_at = self._seq_of.pop(id(handle.request))
            seen = 0
            while True:
                ended = self.control.ended
                with self._cond:
                    why = self._never_entered.pop(id(handle.request), None)
                    if why is None and self._seq == seen:
                        self._cond.wait(WAIT_S)
                        why = self._never_entered.pop(id(handle.request), None)
                if why is not None:
                    how = "canceled" if handle.is_cancel_requested else "abort"
                    return finish(handle, face.failed(how, why))
                with self._cond:
                    fresh = [(s, m) for s, m in self._reports if s > seen]
                    seen = fresh[-1][0] if fresh else seen
                for s, m in fresh:
                    if not m:  # no manager reports: its robot left the run
                        return finish(handle, face.failed("abort", "the robot left the run"))
                    if m.get(f"goal_seq:{name}", 0.0) != float(mine):
                        if m.get(f"goal_seq:{name}", 0.0) > mine:
                            return finish(handle, face.failed("abort",
                                                              "replaced by a newer goal"))
                        if s > put_at and m.get(f"active:{name}") == 0.0:
                            # deactivated before it entered: an inactive controller takes
                            # no message, so it never will
                            return finish(handle, face.failed("abort", DEACTIVATED))
                        continue
                    state = m.get(f"goal_state:{name}")
                    if state == ACTIVE:
                        continue
                    own = {k.rpartition(":")[0]: v for k, v in m.items()
                           if k.endswith(f":{name}")}
                    ending = face.ended(state, own, self.controllers[name],
                                        handle.is_cancel_requested)
                    if ending is not None:
                        return finish(handle, ending)
                if ended is not None:
                    how = "canceled" if handle.is_cancel_requested else "abort"
                    return finish(handle, face.failed(how, f"the run ended: {ended}", -1))
        return execute


def controller_managers(node, group, scenario: Scenario, control: RunControl,
                        arrivals: Arrivals | None, answering
                        ) -> list[ControllerManagerServer]:
    """A server for every robot's controller manager (run in the physics node's step),
    when the run's arrivals are live (an interactive run); ``answering``: see
    ``ControllerManagerServer``."""
    if arrivals is None:
        return []
    out = []
    for plan in scenario.nodes.values():
        if getattr(plan.params, "controller_manager", None) is None:
            continue
        fed = {inp.topic for inp in plan.inputs if inp.producer == EXTERNAL_NAME}
        for robot in plan.spec.robots or [""]:
            namespace = namespace_in(scenario.robots, robot)
            if namespaced(namespace, SWITCH_TOPIC) in fed:
                out.append(ControllerManagerServer(node, group, control, arrivals, plan,
                                                   answering, scenario, robot, namespace))
    return out


def _local(topic: str, namespace: str) -> str:
    """A physics topic of the robot in ``namespace`` as the manager names it ('' when it is
    another robot's)."""
    if not namespace:
        return topic
    head = f"/{namespace}/"
    return topic[len(head) - 1:] if topic.startswith(head) else ""
