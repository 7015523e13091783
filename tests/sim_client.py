"""A plain rclpy client of a running simulation, as a user's script has it: service calls,
action goals with their feedback, parameters and /clock, all on the test's own node."""

from __future__ import annotations

import subprocess
import time
from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import dataclass, field

from rcl_interfaces.srv import GetParameters, SetParameters
from rclpy.action import ActionClient
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from simulation_interfaces.msg import Result, SimulationState
from simulation_interfaces.srv import GetSimulationState, SetSimulationState, StepSimulation

from tests.helpers import ORCHESTRATE, ROOT

OK = Result.RESULT_OK
TIMEOUT_S = 60.0
DISCOVERY_S = 0.5


@dataclass
class Goal:
    """A sent action goal: its handle, the feedback so far and its result future."""

    handle: object
    feedback: list = field(default_factory=list)
    result: object = None


class SimClient:
    """Calls a run's services and actions from the test's rclpy node; its
    simulation_interfaces are at ``namespace`` (the root unless the run was given one)."""

    def __init__(self, ros, namespace: str = "/"):
        self.node, self.executor = ros
        self.ns = namespace.rstrip("/") + "/"
        self.clocks: list[int] = []
        self._clock_sub = self.node.create_subscription(
            Clock, "/clock", lambda m: self.clocks.append(m.clock.sec * 10**9 + m.clock.nanosec),
            QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
        self._actions: dict[str, ActionClient] = {}
        self._clients: dict[str, object] = {}

    def call(self, srv_type, name: str, request, timeout: float = TIMEOUT_S):
        """Call a service and return its response (fail the test if it never answers)."""
        client = self._clients.get(name)
        if client is None:
            client = self._clients[name] = self.node.create_client(srv_type, name)
            assert client.wait_for_service(timeout_sec=timeout), f"{name} never appeared"
            # The client sees the service before the service sees the client's response
            # reader (DDS discovery runs on both sides): a reply sent before that is lost.
            self.spin(DISCOVERY_S)
        future = client.call_async(request)
        self.executor.spin_until_future_complete(future, timeout_sec=timeout)
        assert future.done(), f"{name} did not answer"
        return future.result()

    def close(self) -> None:
        """Forget the clients (a new run has new servers to discover)."""
        for client in self._clients.values():
            self.node.destroy_client(client)
        for client in self._actions.values():
            client.destroy()
        self.node.destroy_subscription(self._clock_sub)
        self._clients, self._actions = {}, {}

    def spin(self, seconds: float) -> None:
        """Take what arrives for a while (feedback, /clock)."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=0.02)

    def spin_until(self, done: Callable[[], bool], timeout: float = TIMEOUT_S) -> None:
        """Spin until ``done()`` or fail at the timeout."""
        end = time.monotonic() + timeout
        while not done():
            assert time.monotonic() < end, "timed out"
            self.executor.spin_once(timeout_sec=0.02)

    def step(self, n: int) -> Result:
        """StepSimulation of ``n`` ticks; returns its result once they are done."""
        return self.call(StepSimulation, self.ns + "step_simulation",
                         StepSimulation.Request(steps=n)).result

    def state(self) -> int:
        """The simulation state (SimulationState.STATE_*)."""
        return self.call(GetSimulationState, self.ns + "get_simulation_state",
                         GetSimulationState.Request()).state.state

    def set_state(self, state: int) -> Result:
        """SetSimulationState."""
        request = SetSimulationState.Request(state=SimulationState(state=state))
        return self.call(SetSimulationState, self.ns + "set_simulation_state", request).result

    def send_goal(self, action_type, name: str, goal, accepted: bool = True) -> Goal:
        """Send an action goal, collecting its feedback; ask for its result. ``accepted``:
        whether the server must accept it (False: it must reject it; no result is asked)."""
        client = self._actions.get(name)
        if client is None:
            client = self._actions[name] = ActionClient(
                self.node, action_type, name, feedback_sub_qos_profile=QoSProfile(depth=100))
            assert client.wait_for_server(timeout_sec=TIMEOUT_S), f"{name} never appeared"
            self.spin(DISCOVERY_S)
        sent = Goal(None)
        future = client.send_goal_async(goal, feedback_callback=lambda m: sent.feedback.append(
            m.feedback))
        self.executor.spin_until_future_complete(future, timeout_sec=TIMEOUT_S)
        sent.handle = future.result()
        assert sent.handle is not None, f"{name}: no answer to the goal"
        if not accepted:
            assert not sent.handle.accepted, f"{name}: goal accepted, expected a rejection"
            return sent
        assert sent.handle.accepted, f"{name}: goal not accepted"
        sent.result = sent.handle.get_result_async()
        return sent

    def result(self, goal: Goal, timeout: float = TIMEOUT_S):
        """Wait for a goal's result (status, result)."""
        self.executor.spin_until_future_complete(goal.result, timeout_sec=timeout)
        assert goal.result.done(), "no result"
        return goal.result.result()

    def cancel(self, goal: Goal) -> None:
        """Ask for a goal's cancellation (the answer, not the result)."""
        future = goal.handle.cancel_goal_async()
        self.executor.spin_until_future_complete(future, timeout_sec=TIMEOUT_S)
        assert future.done(), "no answer to the cancel request"

    def set_param(self, node: str, name: str, value):
        """Set one parameter of a node; returns its SetParametersResult."""
        request = SetParameters.Request(
            parameters=[Parameter(name, value=value).to_parameter_msg()])
        return self.call(SetParameters, f"/{node}/set_parameters", request).results[0]

    def get_param(self, node: str, name: str):
        """One parameter's current value."""
        from rclpy.parameter import parameter_value_to_python

        reply = self.call(GetParameters, f"/{node}/get_parameters",
                          GetParameters.Request(names=[name]))
        return parameter_value_to_python(reply.values[0])


@contextmanager
def orchestrate(scenario, out, *args: str):
    """A cosim-orchestrate process for the block; yields it and leaves none behind."""
    proc = subprocess.Popen([*ORCHESTRATE, str(scenario), "--quiet", "--out", str(out),
                             "--no-picture", *args],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        yield proc
    finally:
        if proc.poll() is None:
            proc.terminate()
            try:
                proc.communicate(timeout=30)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.communicate()


@dataclass
class LiveRun:
    """One paused run a client session drove: its directory, digest, the tick it was stopped
    before, the orchestrator's exit code and standard error."""

    run_dir: object
    digest: str
    stopped_at: int
    returncode: int
    stderr: str


def live_runs(ros, scenario, tmp_path, session: Callable[[SimClient, bool], int],
              times: int = 2) -> list[LiveRun]:
    """Run ``scenario`` paused ``times`` times, each driven by ``session(client, checks)``
    (which returns the tick it stopped the run before; checks only on the first), and
    check each manifest's tick count."""
    import json

    runs = []
    for n in range(times):
        out = tmp_path / f"live{n}"
        sim = SimClient(ros)
        with orchestrate(scenario, out, "--paused") as proc:
            stopped_at = session(sim, n == 0)
            _, err = proc.communicate(timeout=120)
        sim.close()
        run_dir = next(out.iterdir())
        manifest = json.loads((run_dir / "manifest.json").read_text())
        assert manifest["ticks"] == stopped_at, err
        runs.append(LiveRun(run_dir, manifest["digest"], stopped_at, proc.returncode, err))
    return runs
