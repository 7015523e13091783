"""The run's live endpoints (``--live``, ``--rosbridge``), wired to the orchestrator.

- What clients see: every topic of the run and /clock, as the run's driver feeds them
  (``orchestrator.drivers``, ``Driver.feed``: in a multi-process run a thread reads what the
  nodes record as they record it, ``orchestrator.live.live_tail``, nothing added to the
  transport or to the master's loop; an in-process run offers what its observers see). The
  endpoints are attached to the run once, for every driver (``orchestrator.live.attachment``).
  ``offer`` never blocks: the endpoints keep bounded queues and serve from their own
  threads.
- What clients drive: messages enter through the run's ``Arrivals`` (the scenario's
  ``external:`` topics), at the external node's next tick, recorded and hashed; services
  reach the run's simulation services (``orchestrator.ros_surface.sim_services``: ``/cosim/pause``,
  ``/cosim/step``, ``/cosim/reset``, the simulation_interfaces services), each call served
  by their own executor, exactly as a ROS 2 client's call is; what it changes acts between
  ticks.
"""

from __future__ import annotations

import sys
import threading
import time
from typing import Any

from rosgraph_msgs.msg import Clock

from plan.options import RunOptions
from plan.scenario import Scenario
from runtime.live.endpoints import Catalog, ServiceUnavailable
from runtime.live.session import LiveEndpoints
from runtime.protocol import CLOCK_TOPIC

POLL_S = 0.005


class SimControlServices:
    """The services of the run's simulation services node, callable from any thread."""

    def __init__(self, control):
        self.control = control
        # rclpy's own type-description service is no simulation control
        self._services = {srv.srv_name: srv for srv in control.node.services
                          if not srv.srv_type.__module__.startswith("type_description")}

    def types(self) -> dict[str, type]:
        """Service name -> service class."""
        return {name: srv.srv_type for name, srv in self._services.items()}

    def call(self, name: str, request: Any, timeout_s: float) -> Any:
        """Run the service's callback on the services' executor and wait for its
        response."""
        service = self._services.get(name)
        if service is None:
            raise ServiceUnavailable(f"no service {name}")
        try:
            task = self.control.executor.create_task(service.callback, request,
                                                     service.srv_type.Response())
        except Exception as exc:  # noqa: BLE001 - the executor is shut down: the run is over
            raise ServiceUnavailable(f"the run takes no more calls ({exc})") from None
        deadline = time.monotonic() + timeout_s
        while not task.done():
            if time.monotonic() > deadline:
                task.cancel()
                raise ServiceUnavailable(f"{name}: the run did not take the call within "
                                         f"{timeout_s:g} s (it may be over)")
            time.sleep(POLL_S)
        if task.exception() is not None:
            raise ServiceUnavailable(f"{name} failed: {task.exception()}")
        return task.result()


class SimControlActions:
    """The action servers of the run's simulation services node (SimulateSteps, and
    NavigateToPose in an interactive run): a goal runs their own callbacks, as a ROS 2
    client's goal does (``orchestrator.ros_surface.local_goals``)."""

    def __init__(self, control):
        self._actions = dict(control.local_actions)

    def types(self) -> dict[str, type]:
        """Action name -> action class."""
        return {name: action.action_type for name, action in self._actions.items()}

    def run_goal(self, name: str, goal: Any, on_feedback, cancelled, timeout_s: float):
        """Serve ``goal`` to its end, relaying its feedback and cancelling it when
        ``cancelled()``: (status, result message)."""
        from orchestrator.ros_surface.local_goals import GoalRejected

        action = self._actions.get(name)
        if action is None:
            raise ServiceUnavailable(f"no action {name}")
        try:
            return action.run(goal, on_feedback, cancelled)
        except GoalRejected as exc:
            raise ServiceUnavailable(f"{name}: {exc}") from None


def catalog_for(scenario: Scenario, arrivals) -> Catalog:
    """What the endpoints of this run offer: its topics and /clock, its external topics
    (when ``arrivals`` is live); services come with ``attach_control``."""
    topics = {CLOCK_TOPIC: Clock, **dict(sorted(scenario.topics.items()))}
    if arrivals is None:
        why = ("this run takes no messages from outside: give the scenario an external: "
               "section, e.g. external: {rate: 10, topics: {/cmd_vel: geometry_msgs/msg/Twist}}")
    else:
        why = "this run replays recorded inputs and takes none from outside"
    inbox = arrivals if hasattr(arrivals, "put") else None
    return Catalog(topics, inbox=inbox, no_inbox_text=why,
                   latched=frozenset(scenario.latched_topics))


def start_endpoints(scenario: Scenario, options: RunOptions, arrivals,
                    control_later: bool = False) -> LiveEndpoints | None:
    """Start what the options ask for (None when neither); LiveError when one cannot listen.
    ``control_later``: the run's simulation services come once the nodes are ready
    (``attach_control``); clients may connect before."""
    twin = getattr(arrivals, "link", None)  # a digital twin's link to the robot
    if not (options.live or options.rosbridge or twin):
        return None
    end_ns = scenario.schedule.time_ns(max(scenario.schedule.n_ticks - 1, 0))
    endpoints = LiveEndpoints(catalog_for(scenario, arrivals), options.live_address,
                              options.rosbridge_address, f"cosim {scenario.name}", end_ns,
                              control_later, extra={"twin": twin} if twin else None)
    for line in endpoints.start():
        print(f"cosim-orchestrate: {line}", file=sys.stderr, flush=True)
    return endpoints


def prepare_schemas(scenario: Scenario, options: RunOptions) -> None:
    """With ``--live``: build the ``ros2msg`` schemas of the run's topics (and load the
    type store they come from) in a thread while the nodes start, so that starting the
    endpoints, on the orchestrator's way to the first tick, finds them made. Start it only
    once the nodes are started (a thread would keep them from being forked)."""
    if not options.live:
        return
    # imported here, not in the thread: the main thread imports them too meanwhile
    from plan.ros_types import ros_type
    from runtime.live.schemas import message_schema

    types = [Clock, *scenario.topics.values()]

    def warm() -> None:
        try:
            for cls in types:
                message_schema(ros_type(cls))
        except Exception:  # noqa: BLE001 - only a head start: the endpoints do it too
            pass

    threading.Thread(target=warm, name="cosim-live-schemas", daemon=True).start()


def prepare_control(endpoints: LiveEndpoints, services) -> None:
    """Build the ``ros2msg`` schemas of the run's simulation services in a thread while the
    nodes start, so that ``attach_control`` (between the nodes' readiness and the first
    tick, on the run's critical path) finds them made. Best effort: ``attach_control``
    builds whatever this did not."""
    if endpoints.foxglove is None or services is None:
        return

    from plan.ros_types import ros_type
    from runtime.live.schemas import service_schemas

    def warm() -> None:
        try:
            if services.wait_built():
                for srv in SimControlServices(services).types().values():
                    service_schemas(ros_type(srv))
        except Exception:  # noqa: BLE001 - only a head start: attach_control does it too
            pass

    threading.Thread(target=warm, name="cosim-live-schemas", daemon=True).start()


def attach_control(endpoints: LiveEndpoints, services) -> None:
    """Offer the run's simulation services (a SimServices, once built) to the endpoints'
    clients."""
    if services is not None and services.wait_built():
        endpoints.attach_services(SimControlServices(services), SimControlActions(services))
