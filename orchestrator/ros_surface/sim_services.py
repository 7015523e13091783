"""The ROS 2 interfaces of a running simulation (ros2 runs, multi-process).

- simulation_interfaces (Jazzy's 1.5) at the root names, as Isaac Sim's sim_control and
  O3DE serve them (or under the scenario's ``simulation_interfaces.namespace``, e.g.
  ``/cosim``, as Gazebo serves them under ``/gzserver/``): ``get_simulator_features``,
  ``get_simulation_state``, ``set_simulation_state``, ``step_simulation``, the
  ``simulate_steps`` action, ``reset_simulation``, ``get_entities``, ``get_entity_state``,
  ``set_entity_state``, and ``spawn_entity``, ``spawn_entities`` and ``delete_entity`` for
  objects
  (``orchestrator.ros_surface.sim_spawn``);
- ``/cosim/pause`` (std_srvs/SetBool), ``/cosim/step`` and ``/cosim/reset``
  (std_srvs/Trigger): the same state machine with plain types, for rosbridge and Foxglove
  clients;
- ``/navigate_to_pose`` (nav2_msgs NavigateToPose) when the scenario feeds /goal_pose to a
  navigation node from outside (``orchestrator.ros_surface.navigate``);
- every cosim node's parameters (``orchestrator.ros_surface.param_server``).

They run on their own rclpy context, spun by a multi-threaded executor in a thread of the
orchestrator, so a request that waits for the run (a step, a reset, a goal) never holds up
another and never the master: they meet through ``RunControl`` and the run's external
arrivals. Whatever changes the run enters at a tick boundary and is recorded.
"""

from __future__ import annotations

import logging
import re
import threading
import time

from simulation_interfaces.action import SimulateSteps
from simulation_interfaces.msg import Result, SimulationState, SimulatorFeatures
from simulation_interfaces.srv import (
    DeleteEntity,
    GetEntities,
    GetEntityState,
    GetSimulationState,
    GetSimulatorFeatures,
    GetSpawnables,
    ResetSimulation,
    SetEntityState,
    SetSimulationState,
    SpawnEntities,
    SpawnEntity,
    StepSimulation,
)

from orchestrator.ros_surface.local_goals import LocalAction
from orchestrator.ros_surface.simcontrol import PAUSED, PLAYING, Outcome, RunControl
from plan.interactive import GOAL_TOPIC
from plan.run_paths import RunPaths
from plan.scenario import EXTERNAL_NAME, Scenario
from runtime.arrivals import Arrivals
from runtime.transport.ros2 import destroy_node

THREADS = 8  # requests served at once (several may wait for the run)
FLUSH_S = 0.3  # quiet after the last answer, before the services go away (replies in flight)
FLUSH_MAX_S = 2.0  # the longest the services stay after the run for late replies
ANSWER_WAIT_S = 15.0  # how long the end of a run waits for the requests it woke to answer
BUILD_WAIT_S = 30.0
RESET_WAIT_S = 120.0
log = logging.getLogger("cosim")
STATES = {PLAYING: SimulationState.STATE_PLAYING, PAUSED: SimulationState.STATE_PAUSED}
RESETS = ResetSimulation.Request.SCOPE_TIME | ResetSimulation.Request.SCOPE_STATE
F = SimulatorFeatures


class SimServices:
    """The servers, their rclpy context and the thread that builds and spins them (while
    the nodes start: building them takes a few tenths of a second)."""

    def __init__(self, scenario: Scenario, control: RunControl, arrivals: Arrivals | None,
                 paths: RunPaths):
        self.control = control
        self.scenario = scenario
        self.prefix = service_prefix(scenario.model.simulation_interfaces.namespace)
        self.last_answer = 0.0
        self.executor = None
        self._busy = 0  # requests being served (services, action goals executing)
        self._idle = threading.Condition()
        self.robot = _robot(scenario, control, arrivals, paths)
        from orchestrator.ros_surface.sim_spawn import object_spawner

        self.spawner = object_spawner(scenario, control, arrivals, self.robot)
        if self.spawner is not None and self.robot is not None:  # no teleport into them
            self.robot.spawned_obstacles = self.spawner.static_obstacles
        self._built = threading.Event()
        self.thread = threading.Thread(target=self._serve, args=(scenario, arrivals),
                                       name="cosim-ros-interfaces", daemon=True)
        self.thread.start()

    def _serve(self, scenario: Scenario, arrivals: Arrivals | None) -> None:
        from rclpy.executors import ExternalShutdownException

        try:
            self._build(scenario, arrivals)
        except Exception:  # noqa: BLE001 - the run goes on without its ROS 2 interfaces
            log.exception("the run's ROS 2 interfaces could not start")
            self.executor = None
            self._remove_servers()
            return
        finally:
            self._built.set()
        try:
            self.executor.spin_until_future_complete(self._stop)
        except ExternalShutdownException:
            pass

    def _remove_servers(self) -> None:
        """Destroy every node of the servers (those built so far, when building failed) and
        shut their context down: the participant lives while any node of it does, and servers
        left without an executor would be found by clients (of this run and of later runs in
        the same process) and never answer them."""
        import rclpy

        context = getattr(self, "context", None)
        if context is None:
            return
        for params in getattr(self, "parameters", []):
            params.destroy()
        if getattr(self, "node", None) is not None:
            destroy_node(self.node)  # its action servers too
        if context.ok():
            rclpy.shutdown(context=context)

    def _build(self, scenario: Scenario, arrivals: Arrivals | None) -> None:
        import rclpy
        from rclpy.action import ActionServer, CancelResponse
        from rclpy.callback_groups import ReentrantCallbackGroup
        from rclpy.executors import MultiThreadedExecutor
        from rclpy.signals import SignalHandlerOptions

        from orchestrator.ros_surface import reliable_replies
        from orchestrator.ros_surface.param_server import parameter_nodes

        reliable_replies.install()
        started = time.monotonic()
        self.context = rclpy.Context()
        rclpy.init(context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node("cosim_simulation", context=self.context,
                                      start_parameter_services=False, enable_rosout=False)
        group = ReentrantCallbackGroup()
        for srv, name, handler in (
                (GetSimulatorFeatures, "get_simulator_features", self._features),
                (GetSpawnables, "get_spawnables", self._spawnables),
                (GetSimulationState, "get_simulation_state", self._get_state),
                (SetSimulationState, "set_simulation_state", self._set_state),
                (StepSimulation, "step_simulation", self._step),
                (ResetSimulation, "reset_simulation", self._reset),
                (GetEntities, "get_entities", self._entities),
                (GetEntityState, "get_entity_state", self._get_entity),
                (SetEntityState, "set_entity_state", self._set_entity),
                (SpawnEntity, "spawn_entity", self._spawn),
                (SpawnEntities, "spawn_entities", self._spawn_many),
                (DeleteEntity, "delete_entity", self._delete)):
            self.node.create_service(srv, self.prefix + name, self._answering(handler),
                                     callback_group=group)
        from std_srvs.srv import SetBool, Trigger

        for srv, name, handler in ((SetBool, "/cosim/pause", self._pause),
                                   (Trigger, "/cosim/step", self._step_one),
                                   (Trigger, "/cosim/reset", self._reset_soon)):
            self.node.create_service(srv, name, self._answering(handler), callback_group=group)
        self.steps_server = ActionServer(self.node, SimulateSteps,
                                         self.prefix + "simulate_steps",
                                         self._answering(self._simulate_steps),
                                         callback_group=group,
                                         cancel_callback=lambda _: CancelResponse.ACCEPT)
        self.navigate = _navigate(self.node, group, scenario, self.control, arrivals,
                                  self._answering)
        from orchestrator.ros_surface.controller_manager import controller_managers

        self.controller_managers = controller_managers(self.node, group, scenario,
                                                       self.control, arrivals, self._answering)
        # the same callbacks, for goals from the live endpoints (rosbridge's send_action_goal)
        self.local_actions = {self.prefix + "simulate_steps": LocalAction(
            SimulateSteps, None, self._simulate_steps)}
        if self.navigate is not None:
            self.local_actions["/navigate_to_pose"] = self.navigate.local_action()
        self.parameters = []
        for params in parameter_nodes(self.context, scenario, arrivals, self.control):
            self.parameters.append(params)
        from rclpy.task import Future

        self._stop = Future()  # done at close: the spin ends (and wakes to see it)
        executor = MultiThreadedExecutor(num_threads=THREADS, context=self.context)
        for node in [self.node, *(p.node for p in self.parameters)]:
            executor.add_node(node)
        self.executor = executor
        log.info("ROS 2 interfaces up in %.3f s: %sget_simulator_features and the rest, "
                 "%s%d nodes' parameters", time.monotonic() - started, self.prefix,
                 "/navigate_to_pose, " if self.navigate else "", len(self.parameters))

    def wait_built(self) -> bool:
        """Wait until the servers are up; False when they could not start."""
        self._built.wait(BUILD_WAIT_S)
        return self.executor is not None

    def close(self) -> None:
        """The run is over: wake every waiting request, wait until each has answered (an
        active goal ends with a terminal status and why), let the answers and results go
        out (the executor sends an action's result after its callback returns), then
        remove the servers."""
        self.control.finished("the orchestrator stopped the run")
        self._built.wait(BUILD_WAIT_S)
        if self.executor is None:
            return
        with self._idle:
            if not self._idle.wait_for(lambda: self._busy == 0, timeout=ANSWER_WAIT_S):
                log.warning("%d request(s) of the run's ROS 2 interfaces still unanswered "
                            "after %g s; closing them", self._busy, ANSWER_WAIT_S)
        closing = time.monotonic()
        while (time.monotonic() - self.last_answer < FLUSH_S
               and time.monotonic() - closing < FLUSH_MAX_S):
            time.sleep(0.05)
        # The spin ends first, then the callbacks it handed to the executor's threads finish,
        # and only then are the executor's guard condition and the nodes destroyed: rclpy
        # (Jazzy) Executor.shutdown does not wait for those callbacks (it skips its own
        # wait), and one that runs later (a controller_state message taken for feedback)
        # triggers the destroyed guard or takes from a destroyed subscription: "The
        # following exception was never retrieved: cannot use Destroyable".
        self._stop.set_result(None)
        self.thread.join(timeout=5.0)
        with self._idle:
            idle = self._busy == 0
        if not self.thread.is_alive() and idle:  # no request left that could block it
            _drain(self.executor)
        self.executor.shutdown(timeout_sec=5.0)
        self._remove_servers()

    def _answering(self, handler):
        """``handler`` counted while it serves (close waits for it) and timed."""
        def serve(*args):
            with self._idle:
                self._busy += 1
            try:
                return handler(*args)
            finally:
                with self._idle:
                    self._busy -= 1
                    self.last_answer = time.monotonic()
                    self._idle.notify_all()
        return serve

    # -- simulation state ------------------------------------------------------------------

    def _features(self, request, response):
        features = [F.SIMULATION_STATE_GETTING, F.SIMULATION_STATE_SETTING,
                    F.SIMULATION_STATE_PAUSE, F.STEP_SIMULATION_SINGLE,
                    F.STEP_SIMULATION_MULTIPLE, F.STEP_SIMULATION_ACTION, F.SPAWNABLES]
        if self.control.cannot_reset is None:
            features.append(F.SIMULATION_RESET)
        if self.robot is not None:
            features.append(F.ENTITY_STATE_GETTING)
            if self.robot.teleport_topic is not None:
                features.append(F.ENTITY_STATE_SETTING)
        if self.spawner is not None:
            features += [F.SPAWNING, F.SPAWNING_RESOURCE_STRING, F.SPAWNING_ENTITIES,
                         F.DELETING]
            from orchestrator.ros_surface.spawn_resources import FORMATS

            response.features.spawn_formats = list(FORMATS)
        response.features.features = sorted(features)
        objects = ("; objects (one link: box, cylinder, sphere, mesh) can be spawned and "
                   "deleted" if self.spawner is not None else "")
        response.features.custom_info = (
            "cosim: a deterministic lockstep co-simulation; one tick per step; services "
            f"under {self.prefix}; a reset covers time and state together; entities: the "
            f"robot and spawned objects{objects}; robots enter and leave through the "
            "scenario's events:, or a SpawnEntity of a robot its spawnables: plan "
            "(docs/how-to/world-events.md); get_spawnables lists the spawnables; see "
            "docs/how-to/ros-interfaces.md")
        return response

    def _spawnables(self, request, response):
        from simulation_interfaces.msg import Spawnable

        from orchestrator.ros_surface.spawnables import list_spawnables

        found, unknown = list_spawnables(self.scenario, list(request.sources))
        response.spawnables = [Spawnable(uri=uri, description=text) for uri, text in found]
        response.result = (_result(Result.RESULT_OK, "") if not unknown else _result(
            Result.RESULT_NOT_FOUND, "sources not listed: " + " ".join(unknown)))
        return response

    def _get_state(self, request, response):
        response.state.state = STATES.get(self.control.state, SimulationState.STATE_STOPPED)
        response.result = _result(Result.RESULT_OK, self.control.where())
        return response

    def _set_state(self, request, response):
        target = request.state.state
        if target == SimulationState.STATE_PLAYING:
            out = self.control.play()
        elif target == SimulationState.STATE_PAUSED:
            out = self.control.pause()
        elif target in (SimulationState.STATE_STOPPED, SimulationState.STATE_QUITTING):
            out = self.control.stop()
            if out.code == "ended":
                out.code = "state"  # already stopped
        else:
            response.result = _result(Result.RESULT_FEATURE_UNSUPPORTED,
                                      f"state {target}: cosim has no world loading")
            return response
        codes = {"state": SetSimulationState.Response.ALREADY_IN_TARGET_STATE,
                 "ended": SetSimulationState.Response.INCORRECT_TRANSITION}
        response.result = _from_outcome(out, codes)
        return response

    def _step(self, request, response):
        response.result = _from_outcome(self.control.step(int(request.steps)))
        return response

    def _simulate_steps(self, handle):
        n = int(handle.request.steps)

        def feedback(done: int) -> None:
            handle.publish_feedback(SimulateSteps.Feedback(completed_steps=done,
                                                           remaining_steps=n - done))

        out = self.control.step(n, feedback, lambda: handle.is_cancel_requested)
        self.last_answer = time.monotonic()
        if out.code == "cancelled" and handle.is_cancel_requested:
            handle.canceled()
            return SimulateSteps.Result(result=_result(Result.RESULT_OK, out.message))
        if out.ok:
            handle.succeed()
        else:
            handle.abort()
        return SimulateSteps.Result(result=_from_outcome(out))

    def _reset(self, request, response):
        scope = request.scope
        if scope not in (ResetSimulation.Request.SCOPE_DEFAULT,) and scope & RESETS != RESETS:
            response.result = _result(Result.RESULT_FEATURE_UNSUPPORTED, (
                f"scope {scope}: cosim resets time and state together (SCOPE_ALL or "
                "SCOPE_TIME | SCOPE_STATE; spawned objects go with the state: the world is "
                "the scenario's again)"))
            return response
        out = self.control.reset()
        if out.ok:
            for params in self.parameters:
                params.reset()
        response.result = _from_outcome(out)
        return response

    # -- the std_srvs services: simple types for rosbridge and Foxglove clients -----------

    def _words(self) -> str:
        """'paused at tick 12 (sim time 0.240000000 s)', or 'running at ...'."""
        word = "paused" if self.control.state == PAUSED else "running"
        return f"{word} at {self.control.at()}"

    def _pause(self, request, response):
        """true pauses before the next tick, false resumes; pausing again only reports."""
        out = self.control.pause() if request.data else self.control.play()
        response.success = out.ok or out.code == "state"
        response.message = self._words() if response.success else out.message
        return response

    def _step_one(self, request, response):
        """One tick while paused; answers at once."""
        before = self._words()
        out = self.control.add_step()
        response.success = out.ok
        response.message = f"{out.message}; {before}" if out.code != "ended" else out.message
        if out.code == "state":
            response.message = f"not paused: pause first; {before}"
        return response

    def _reset_soon(self, request, response):
        """Back to tick 0 with the same seed; answers at once, the reset follows."""
        before, epoch = self._words(), self.control.epoch
        out = self.control.request_reset()
        response.success = out.ok
        response.message = f"{out.message}; was {before}" if out.ok else (
            f"{out.message}; {before}")
        if out.ok:
            threading.Thread(target=self._after_reset, args=(epoch,), daemon=True).start()
        return response

    def _after_reset(self, epoch: int) -> None:
        """Once a reset asked for through /cosim/reset is done: parameters as at the start."""
        if self.control.wait_reset(epoch, RESET_WAIT_S):
            for params in self.parameters:
                params.reset()

    # -- entities ---------------------------------------------------------------------------

    def _entities(self, request, response):
        f = request.filters
        if f.categories or f.tags.tags or f.bounds.type or f.bounds.points:
            response.result = _result(Result.RESULT_FEATURE_UNSUPPORTED,
                                      "cosim filters entities by name only")
            return response
        try:
            pattern = re.compile(f.filter)
        except re.error as exc:
            response.result = _result(Result.RESULT_OPERATION_FAILED,
                                      f"filter {f.filter!r} is not a regular expression: {exc}")
            return response
        names = [self.robot.name] if self.robot is not None else []
        if self.spawner is not None:
            names += sorted(self.spawner.live())
        response.entities = [n for n in names if pattern.search(n)]
        response.result = _result(Result.RESULT_OK, "")
        return response

    def _get_entity(self, request, response):
        if self.robot is None or request.entity != self.robot.name:
            response.result = self._not_found(request.entity)
            return response
        state, why = self.robot.state()
        if state is None:
            response.result = _result(Result.RESULT_OPERATION_FAILED, why)
            return response
        response.state = state
        response.result = _result(Result.RESULT_OK, "")
        return response

    def _set_entity(self, request, response):
        if self.robot is None or request.entity != self.robot.name:
            response.result = self._not_found(request.entity)
            return response
        response.result = _result(*self.robot.set_state(request))
        return response

    def _spawn(self, request, response):
        if self.spawner is None:
            response.result = _result(Result.RESULT_FEATURE_UNSUPPORTED, _NO_EDITS)
            return response
        code, text, name = self.spawner.spawn(request)
        response.result, response.entity_name = _result(code, text), name
        return response

    def _spawn_many(self, request, response):
        from simulation_interfaces.msg import SpawnResult

        if self.spawner is None:
            response.result = _result(Result.RESULT_FEATURE_UNSUPPORTED, _NO_EDITS)
            return response
        failed = 0
        for one in request.spawn_requests:
            code, text, name = self.spawner.spawn(SpawnEntity.Request(
                name=one.name, allow_renaming=one.allow_renaming,
                uri=one.entity_resource.uri,
                resource_string=one.entity_resource.resource_string,
                entity_namespace=one.entity_namespace, initial_pose=one.initial_pose))
            response.results.append(SpawnResult(result=_result(code, text), entity_name=name))
            failed += code != Result.RESULT_OK
        response.result = (_result(Result.RESULT_OK, "") if not failed else _result(
            SpawnEntities.Response.ENTITIES_SPAWN_FAILED,
            f"{failed} of {len(request.spawn_requests)} refused: see results"))
        return response

    def _delete(self, request, response):
        if self.spawner is None:
            response.result = _result(Result.RESULT_FEATURE_UNSUPPORTED, _NO_EDITS)
            return response
        response.result = _result(*self.spawner.delete(request.entity))
        return response

    def _not_found(self, entity: str) -> Result:
        known = f"the only entity is {self.robot.name!r}" if self.robot else "there is none"
        return _result(Result.RESULT_NOT_FOUND, f"no entity {entity!r}: {known}")


_NO_EDITS = ("cannot spawn or delete: the scenario is not interactive (set interactive: true), "
             "has no world, or this run replays recorded inputs.")


def _drain(executor) -> None:
    """Wait until every callback a stopped MultiThreadedExecutor handed to its threads has
    finished (rclpy keeps them in its thread pool, ``_executor``; an executor without one
    runs its callbacks in the spinning thread, which has ended)."""
    from concurrent.futures import ThreadPoolExecutor

    pool = getattr(executor, "_executor", None)
    if isinstance(pool, ThreadPoolExecutor):
        pool.shutdown(wait=True)


def service_prefix(namespace: str) -> str:
    """'/' for the root ('' or '/'), '/cosim/' for '/cosim' or '/cosim/'."""
    return "/" + "".join(f"{part}/" for part in namespace.split("/") if part)


def start_services(scenario: Scenario, control: RunControl, arrivals: Arrivals | None,
                   paths: RunPaths) -> SimServices:
    """Start a run's ROS 2 interfaces (before its nodes are ready: clients may wait)."""
    return SimServices(scenario, control, arrivals, paths)


def _robot(scenario: Scenario, control: RunControl, arrivals: Arrivals | None,
           paths: RunPaths):
    """The robot entity of the scenario's physics node (one with /odom and a base body)."""
    from orchestrator.ros_surface.sim_entities import RobotEntity

    for plan in scenario.nodes.values():
        if (not plan.role.is_foreign and "/odom" in plan.output_names
                and isinstance(getattr(plan.params, "base_body", None), str)):
            return RobotEntity(scenario, plan, control, arrivals, paths.part(plan.name))
    return None


def _navigate(node, group, scenario: Scenario, control: RunControl, arrivals: Arrivals | None,
              counted=None):
    """The NavigateToPose server, when a node takes /goal_pose from the external node and
    the run's arrivals are live."""
    from orchestrator.ros_surface.navigate import NavigateServer

    if arrivals is None:
        return None
    for plan in scenario.nodes.values():
        for inp in plan.inputs:
            if (inp.topic == GOAL_TOPIC and inp.producer == EXTERNAL_NAME
                    and inp.graph_topic in arrivals.topics):
                return NavigateServer(node, group, control, arrivals, plan.name,
                                      inp.graph_topic, scenario.tick_ns, counted)
    return None


def _result(code: int, text: str) -> Result:
    return Result(result=code, error_message=text)


def _from_outcome(out: Outcome, codes: dict[str, int] | None = None) -> Result:
    if out.ok:
        return _result(Result.RESULT_OK, out.message)
    return _result((codes or {}).get(out.code, Result.RESULT_OPERATION_FAILED), out.message)
