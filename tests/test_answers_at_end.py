"""Every request in flight when a run ends gets its answer, and an active goal a terminal
status with a message, before the run's ROS interfaces close (issue 40, item 4): a plain
rclpy client on a --paused nav run, a goal sent, steps asked for past the run's end."""

from __future__ import annotations

import pytest
import yaml
from nav2_msgs.action import NavigateToPose
from simulation_interfaces.action import SimulateSteps
from simulation_interfaces.srv import StepSimulation

from tests.helpers import nav_without_camera_doc
from tests.sim_client import SimClient, orchestrate
from tests.test_ros_clients_nav import ABORTED, FAR, nav_goal

TICKS = 75  # the run's duration, 1.5 s of 20 ms ticks


@pytest.fixture(scope="module")
def scenario_file(tmp_path_factory):
    """nav without the camera, interactive, 1.5 s."""
    doc = nav_without_camera_doc("1.5s")
    doc["interactive"] = True
    path = tmp_path_factory.mktemp("nav") / "nav_end.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


@pytest.mark.parametrize("steps_by", ["service", "action"])
def test_requests_in_flight_at_the_end_of_a_run_are_answered(tmp_path, ros_node, scenario_file,
                                                             steps_by):
    sim = SimClient(ros_node)
    with orchestrate(scenario_file, tmp_path / "out", "--paused") as proc:
        goal = sim.send_goal(NavigateToPose, "/navigate_to_pose", nav_goal(*FAR))
        if steps_by == "service":  # more steps than the run has left
            client = ros_node[0].create_client(StepSimulation, "/step_simulation")
            assert client.wait_for_service(timeout_sec=60)
            sim.spin(0.5)
            answer = client.call_async(StepSimulation.Request(steps=TICKS * 4))
        else:
            steps = sim.send_goal(SimulateSteps, "/simulate_steps",
                                  SimulateSteps.Goal(steps=TICKS * 4))
            answer = steps.result
        sim.spin_until(lambda: goal.result.done() and answer.done(), timeout=120)
        outcome = goal.result.result()
        assert outcome.status == ABORTED
        assert "the run ended" in outcome.result.error_msg, outcome.result.error_msg
        assert len(goal.feedback) > 5
        reply = answer.result()
        result = reply.result if steps_by == "service" else reply.result.result
        assert result.result != 1 and "ended" in result.error_message, result.error_message
        proc.communicate(timeout=60)
    sim.close()
