"""simulation_interfaces on a real multi-process run, from a plain rclpy client: features,
state, stepping (the service and the action, with feedback and a cancel), reset, stop; at the
root names by default (as Isaac Sim and O3DE serve them), under a namespace on request."""

from __future__ import annotations

import json

from rclpy.qos import QoSProfile, ReliabilityPolicy
from simulation_interfaces.action import SimulateSteps
from simulation_interfaces.msg import Result, SimulationState, SimulatorFeatures
from simulation_interfaces.srv import (
    GetEntities,
    GetEntityState,
    GetSimulatorFeatures,
    ResetSimulation,
    SetSimulationState,
)

from descriptions.load import load_scenario
from orchestrator.lockstep.inprocess import run_in_process
from tests.helpers import SCENARIOS
from tests.sim_client import OK, SimClient, orchestrate

PROTOCOL = SCENARIOS / "protocol.yaml"  # 100 Hz ticks; here 20 s long: 2001 ticks
LONG = SCENARIOS / "long_chain.yaml"  # 100 Hz ticks, an hour
DURATION = "20s"  # long enough that a cancel comes before the run's end
TICK_NS = 10_000_000
F = SimulatorFeatures
PAUSED, PLAYING, STOPPED = (SimulationState.STATE_PAUSED, SimulationState.STATE_PLAYING,
                            SimulationState.STATE_STOPPED)


def test_step_simulate_cancel_reset_play(tmp_path, ros_node):
    sim = SimClient(ros_node)
    with orchestrate(PROTOCOL, tmp_path, "--paused", "--duration", DURATION) as run:
        features = sim.call(GetSimulatorFeatures, "/get_simulator_features",
                            GetSimulatorFeatures.Request()).features
        services = dict(sim.node.get_service_names_and_types())
        assert services["/step_simulation"] == ["simulation_interfaces/srv/StepSimulation"]
        assert not any(n.startswith("/cosim/") and "simulation" in n for n in services)
        assert "/cosim/pause" in services  # the std_srvs services stay where they were
        assert sorted(features.features) == sorted([
            F.SIMULATION_STATE_GETTING, F.SIMULATION_STATE_SETTING, F.SIMULATION_STATE_PAUSE,
            F.STEP_SIMULATION_SINGLE, F.STEP_SIMULATION_MULTIPLE, F.STEP_SIMULATION_ACTION,
            F.SIMULATION_RESET, F.SPAWNABLES])  # no robot here: no entity features
        assert sim.state() == PAUSED
        assert sim.set_state(PAUSED).result == SetSimulationState.Response.ALREADY_IN_TARGET_STATE

        # StepSimulation: exactly 10 ticks, answered once they are done
        assert sim.step(10).result == OK
        sim.spin_until(lambda: len(sim.clocks) >= 10)  # /clock may trail the answer
        assert sim.clocks == [k * TICK_NS for k in range(10)]
        assert sim.step(10).result == OK  # (and any 11th /clock would show up below)
        sim.spin_until(lambda: len(sim.clocks) >= 20)
        assert sim.clocks == [k * TICK_NS for k in range(20)]
        assert sim.state() == PAUSED

        # SimulateSteps: feedback after every step. Read on the action's feedback topic: an
        # action client drops feedback that comes before it has heard its goal accepted.
        feedback = []
        sim.node.create_subscription(
            SimulateSteps.Impl.FeedbackMessage, "/simulate_steps/_action/feedback",
            lambda m: feedback.append((m.feedback.completed_steps, m.feedback.remaining_steps)),
            QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
        goal = sim.send_goal(SimulateSteps, "/simulate_steps", SimulateSteps.Goal(steps=5))
        status, result = _status_result(sim.result(goal))
        sim.spin_until(lambda: len(feedback) >= 5 and len(sim.clocks) >= 25)
        assert result.result.result == OK, result.result.error_message
        assert feedback == [(1, 4), (2, 3), (3, 2), (4, 1), (5, 0)]
        assert sim.clocks[-1] == 24 * TICK_NS

        # ... cancelled: no tick starts after the cancel, the result says how many ran
        goal = sim.send_goal(SimulateSteps, "/simulate_steps",
                             SimulateSteps.Goal(steps=10_000))
        sim.spin_until(lambda: len(feedback) >= 8)
        sim.cancel(goal)
        status, result = _status_result(sim.result(goal))
        assert status == 5, result  # GoalStatus.STATUS_CANCELED
        ran = int(result.result.error_message.split("after ")[1].split(" of")[0])
        sim.spin_until(lambda: len(sim.clocks) >= 25 + ran)
        assert 3 <= ran < 1000 and len(sim.clocks) == 25 + ran
        assert sim.clocks == [k * TICK_NS for k in range(25 + ran)]

        # reset: only time and state together; then the run equals a fresh one
        reply = sim.call(ResetSimulation, "/reset_simulation",
                         ResetSimulation.Request(scope=ResetSimulation.Request.SCOPE_TIME))
        assert reply.result.result == Result.RESULT_FEATURE_UNSUPPORTED
        reply = sim.call(ResetSimulation, "/reset_simulation", ResetSimulation.Request())
        assert reply.result.result == OK, reply.result.error_message
        assert sim.state() == PAUSED
        assert sim.step(3).result == OK

        # no robot here: no entities
        assert sim.call(GetEntities, "/get_entities", GetEntities.Request()).entities == []
        reply = sim.call(GetEntityState, "/get_entity_state",
                         GetEntityState.Request(entity="base_link"))
        assert reply.result.result == Result.RESULT_NOT_FOUND

        assert sim.set_state(PLAYING).result == OK
        out, err = run.communicate(timeout=120)
    assert run.returncode == 0, err
    fresh = run_in_process(load_scenario(PROTOCOL, {"duration": DURATION})).digest
    assert f"digest {fresh}" in out  # the run after the reset equals a fresh run


def test_stepping_needs_a_pause_and_stopping_ends_the_run(tmp_path, ros_node):
    sim = SimClient(ros_node)
    with orchestrate(LONG, tmp_path, "--duration", "1000s") as run:
        sim.spin_until(lambda: len(sim.clocks) > 5)
        assert sim.state() == PLAYING
        reply = sim.step(1)
        assert reply.result == Result.RESULT_OPERATION_FAILED
        assert reply.error_message.startswith("not paused")
        reply = sim.set_state(STOPPED)
        assert reply.result == OK and "stopped by request before tick" in reply.error_message
        stopped_at = int(reply.error_message.split("before tick ")[1].split()[0])
        out, err = run.communicate(timeout=60)
    assert run.returncode == 0, err
    # the /clock messages still queued here
    sim.spin_until(lambda: sim.clocks[-1] >= (stopped_at - 1) * TICK_NS)
    manifest = json.loads(next(tmp_path.glob("*/manifest.json")).read_text())
    assert manifest["ticks"] == stopped_at and sim.clocks[-1] == (stopped_at - 1) * TICK_NS
    # every tick before the stop finished and was recorded: the run equals a shorter one
    shorter = load_scenario(LONG, {"duration": f"{(stopped_at - 1) * 10}ms"})
    assert manifest["digest"] == run_in_process(shorter).digest


def _status_result(response):
    return response.status, response.result


def test_a_namespace_moves_them(tmp_path, ros_node):
    sim = SimClient(ros_node, "/cosim")
    with orchestrate(PROTOCOL, tmp_path, "--paused", "--sim-namespace", "/cosim") as run:
        assert sim.state() == PAUSED  # /cosim/get_simulation_state
        features = sim.call(GetSimulatorFeatures, "/cosim/get_simulator_features",
                            GetSimulatorFeatures.Request()).features
        assert "under /cosim/" in features.custom_info
        assert sim.step(3).result == OK
        services = {n for n, _ in sim.node.get_service_names_and_types()}
        assert {"/cosim/step_simulation", "/cosim/simulate_steps/_action/send_goal",
                "/cosim/get_entity_state"} <= services
        assert not {"/step_simulation", "/get_simulator_features"} & services
        assert sim.set_state(STOPPED).result == OK
        out, err = run.communicate(timeout=60)
    assert run.returncode == 0, err
