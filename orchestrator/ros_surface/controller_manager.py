"""The controller manager's face of an interactive run with a ``ros2_control`` node: the
services ``/controller_manager/list_controllers``, ``list_controller_types`` and
``switch_controller``, and the actions controllers offer (a trajectory controller's
``~/follow_joint_trajectory``, a parallel gripper's ``~/gripper_cmd``: their faces in
``controller_actions``).

What changes the run (a goal, a cancel, a switch) is put into the run's external arrivals and
enters the controller manager node at its next activation, at a tick boundary, recorded like
any message; the answers follow the node's metrics of the ticks the master decides (its
controllers' states, each trajectory controller's newest goal: number, state, result code).
"""

from __future__ import annotations

import logging
import threading
from collections import deque

from controller_manager_msgs.msg import ControllerState
from controller_manager_msgs.srv import ListControllers, ListControllerTypes, SwitchController
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.qos import QoSProfile
from std_msgs.msg import String

from nodes.registry import KINDS
from nodes.ros2_control.controllers.joint_trajectory_controller import (
    ACTIVE,
    CANCEL_ID,
    GOAL,
    GOAL_ID,
)
from nodes.ros2_control.manager import load, resolve, switch_problem
from nodes.ros2_control.node import SWITCH_TOPIC, at_start, read
from nodes.ros2_control.registry import BASE_CLASS, served_types
from orchestrator.ros_surface.controller_actions import FACES
from orchestrator.ros_surface.simcontrol import PAUSED, RunControl
from plan.scenario import EXTERNAL_NAME, Scenario
from runtime.arrivals import Arrivals

WAIT_S = 0.1
PREFIX = "/controller_manager/"
log = logging.getLogger("cosim")


class ControllerManagerServer:
    """list/switch controllers and the trajectory controllers' actions of one node."""

    def __init__(self, node, group, control: RunControl, arrivals: Arrivals, plan,
                 answering=lambda handler: handler):
        """``answering`` wraps the handlers that wait on the run (switch_controller, a goal's
        execution) so that the end of the run waits for their answers before the servers go
        (``SimServices.close``): a goal open when the run ends gets its result."""
        self.control = control
        self.arrivals = arrivals
        self.manager = plan.name
        self.file = read(plan.params)
        self.topics = {inp.topic: inp.graph_topic for inp in plan.inputs
                       if inp.producer == EXTERNAL_NAME}
        self.controllers = load(self.file)  # what each claims and offers, from its parameters
        self.active = {name: name in at_start(plan.params, self.file)
                       and self.controllers[name] is not None for name in self.controllers}
        self._cond = threading.Condition()
        self._reports: deque[tuple[int, dict[str, float]]] = deque(maxlen=4096)
        self._seq = 0
        self._goals_put: dict[str, int] = {}
        self._latest: dict[str, object] = {}
        self._sent = 0  # goals and cancels put, which name them
        self._seq_of: dict[int, int] = {}  # id of a goal request -> its number
        self._never_entered: dict[int, str] = {}  # id of a goal request -> why
        node.create_service(ListControllers, PREFIX + "list_controllers", self._list,
                            callback_group=group)
        node.create_service(ListControllerTypes, PREFIX + "list_controller_types", self._types,
                            callback_group=group)
        node.create_service(SwitchController, PREFIX + "switch_controller",
                            answering(self._switch), callback_group=group)
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
                    topic = resolve(name, face.feedback_topic)
                    node.create_subscription(
                        ctrl.publications()[face.feedback_topic], topic, self._feedback(name),
                        QoSProfile(depth=10), callback_group=group)
                self.actions.append(ActionServer(
                    node, action, resolve(name, action_name),
                    answering(self._executor(name)), callback_group=group,
                    goal_callback=self._goal_callback(name),
                    cancel_callback=self._cancel_callback(name)))
        control.observers.append(self._observe)

    def _observe(self, tick: int, reports: dict) -> None:
        done = reports.get(self.manager)
        if done is None:
            return
        with self._cond:
            self._seq += 1
            self._reports.append((self._seq, dict(done.metrics)))
            for name in self.active:
                if f"active:{name}" in done.metrics:
                    self.active[name] = bool(done.metrics[f"active:{name}"])
            self._cond.notify_all()

    def _list(self, request, response):
        with self._cond:
            active = dict(self.active)
        for entry in self.file.controllers:
            ctrl = self.controllers[entry.name]
            state = ControllerState(name=entry.name, type=entry.type,
                                    state=_state(ctrl, active[entry.name]),
                                    update_rate=self.file.update_rate)
            if ctrl is not None:
                claim = ctrl.claim()
                state.required_command_interfaces = list(claim.command)
                state.required_state_interfaces = list(claim.state)
                if active[entry.name]:  # an inactive controller claims nothing
                    state.claimed_interfaces = list(claim.command)
            response.controller.append(state)
        return response

    def _types(self, request, response):
        response.types = served_types()
        response.base_classes = [BASE_CLASS] * len(response.types)
        return response

    def _switch(self, request, response):
        with self._cond:
            active = [n for n, a in self.active.items() if a]
        problem = switch_problem(self.file, self.controllers, active,
                                 list(request.activate_controllers),
                                 list(request.deactivate_controllers))
        if problem:
            response.ok = False
            response.message = problem
            return response
        msg = String(data=" ".join([*(f"-{n}" for n in request.deactivate_controllers),
                                    *(f"+{n}" for n in request.activate_controllers)]))
        with self._cond:
            seen = self._seq
            self.arrivals.put(self.topics[SWITCH_TOPIC], msg)
        if self.control.state == PAUSED:  # it cannot wait for a tick nobody asks for
            response.ok = True
            response.message = f"the switch enters at {self.control.at()} (the run is paused)"
            return response
        wanted = {**{n: False for n in request.deactivate_controllers},
                  **{n: True for n in request.activate_controllers}}
        while True:
            ended = self.control.ended
            with self._cond:
                if self._seq == seen:
                    self._cond.wait(WAIT_S)
                fresh = [m for s, m in self._reports if s > seen]
            if any(all(m.get(f"active:{n}") == float(v) for n, v in wanted.items())
                   for m in fresh):
                response.ok = True
                return response
            if ended is not None:
                response.ok = False
                response.message = f"the run ended before the switch: {ended}"
                return response

    def _goal_callback(self, name: str):
        face = self.faces[name]
        label = face.action.__name__

        def on_goal(request) -> GoalResponse:
            with self._cond:
                if not self.active[name]:  # as upstream: nothing would ever answer it
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
                else:  # a goal that enters: the controller counts it
                    self._goals_put[name] = self._goals_put.get(name, 0) + 1
                self._seq_of[id(request)] = self._goals_put[name]
                self._latest[name] = request
            log.info("%s: goal %d for %s from %s", label, self._goals_put[name], name,
                     self.control.at())
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
                        self._goals_put[name] -= 1
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
                mine = self._seq_of.pop(id(handle.request))
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
                for _, m in fresh:
                    if m.get(f"goal_seq:{name}", 0.0) != float(mine):
                        if m.get(f"goal_seq:{name}", 0.0) > mine:
                            return finish(handle, face.failed("abort",
                                                              "replaced by a newer goal"))
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


def _state(ctrl, active: bool) -> str:
    """A controller's lifecycle state as list_controllers says it (a type cosim cannot run
    is loaded and never configured)."""
    if ctrl is None:
        return "unconfigured"
    return "active" if active else "inactive"


def controller_managers(node, group, scenario: Scenario, control: RunControl,
                        arrivals: Arrivals | None, answering
                        ) -> list[ControllerManagerServer]:
    """A server for every ros2_control node of the scenario, when the run's arrivals are
    live (an interactive run); ``answering``: see ``ControllerManagerServer``."""
    if arrivals is None:
        return []
    return [ControllerManagerServer(node, group, control, arrivals, plan, answering)
            for plan in scenario.nodes.values() if plan.class_ref == KINDS["ros2_control"]
            and any(inp.topic == SWITCH_TOPIC and inp.producer == EXTERNAL_NAME
                    for inp in plan.inputs)]
