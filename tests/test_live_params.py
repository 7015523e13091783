"""Parameters that change while a run goes, without a run: what an interactive scenario
wires, how a node's Params become ROS 2 parameters (real rclpy services, set through the
standard parameter client), how a change is checked, carried and applied."""

from __future__ import annotations

import pytest
import yaml
from rclpy.parameter import Parameter

from descriptions.load import load_scenario
from nodes.control.node import ControlParams
from nodes.live_params import ParamsInput, change_message, changes_in, flatten, with_changes
from orchestrator.ros_surface.simcontrol import RunControl
from plan.errors import ScenarioError
from runtime.arrivals import Arrivals
from tests.helpers import ROOT, SCENARIOS

NAV = ROOT / "scenarios" / "nav.yaml"


def test_an_interactive_scenario_feeds_goal_teleport_and_parameters_from_outside():
    scenario = load_scenario(NAV, {"interactive": True})
    inputs = {name: [i.topic for i in plan.inputs] for name, plan in scenario.nodes.items()}
    assert inputs["control"] == ["/odom", "/scan", "/goal_pose", "/cosim/params/control"]
    assert inputs["physics"] == ["/cmd_vel", "/cosim/set_pose", "/cosim/world_edits"]
    assert inputs["lidar"] == ["/cosim/world_state"]  # sensors have no runtime parameters
    external = scenario.nodes["external"]
    assert set(external.outputs) == {"/goal_pose", "/cosim/set_pose", "/cosim/params/control",
                                     "/cosim/world_edits"}
    assert external.spec.period_ns == 20_000_000  # the fastest node's rate: physics, 50 Hz
    assert "external" not in load_scenario(NAV).nodes  # not interactive: nothing added
    plain = load_scenario(SCENARIOS / "protocol.yaml", {"interactive": True})
    assert "external" not in plain.nodes  # nothing in it takes what clients send


def test_an_external_topic_of_another_type_is_refused(tmp_path):
    doc = yaml.safe_load(NAV.read_text())
    doc["world"] = str((NAV.parent / doc["world"]).resolve())
    doc["interactive"] = True
    doc["external"] = {"rate": 10, "topics": {"/goal_pose": "geometry_msgs/msg/Pose"}}
    path = tmp_path / "clash.yaml"
    path.write_text(yaml.safe_dump(doc))
    with pytest.raises(ScenarioError, match=r"external\.topics\./goal_pose.*PoseStamped"):
        load_scenario(path)


def test_changes_are_checked_cumulative_and_applied_once():
    params = ControlParams()
    assert flatten(params)["max_speed"] == 0.5
    changed = with_changes(params, {"max_speed": 0.3})
    assert changed.max_speed == 0.3 and params.max_speed == 0.5
    with pytest.raises(ValueError, match="greater than 0"):
        with_changes(params, {"max_speed": -1.0})
    msg = change_message("control", {"max_speed": 0.3, "lookahead": 0.8})
    assert changes_in(msg) == {"lookahead": 0.8, "max_speed": 0.3}

    class Node:
        def __init__(self):
            self.sets = []

        def set_params(self, p):
            self.sets.append(p)

    node, taker = Node(), ParamsInput("control", params)
    topic = "/cosim/params/control"
    default = change_message("", {})  # what the external node holds before any change
    assert taker.apply(node, {topic: default, "/odom": 1}) == {"/odom": 1}
    taker.apply(node, {topic: msg})
    taker.apply(node, {topic: change_message("control", {"max_speed": 0.3,
                                                          "lookahead": 0.8})})  # again
    assert [(p.max_speed, p.lookahead) for p in node.sets] == [(0.3, 0.8)]
    taker.forget()  # a reset: the same message is news again
    taker.apply(node, {topic: msg})
    assert len(node.sets) == 2


@pytest.fixture
def parameters(ros_node):
    """The control node's parameters of an interactive nav run, served on the test's
    context, with the arrivals they put changes into."""
    from nodes.registry import load_class
    from orchestrator.ros_surface.param_server import NodeParameters

    node, executor = ros_node
    scenario = load_scenario(NAV, {"interactive": True})
    arrivals = Arrivals(scenario.nodes["external"].outputs)
    control = RunControl(scenario.tick_ns, paused=True)
    plan = scenario.nodes["control"]
    served = NodeParameters(node.context, plan, load_class(plan.class_ref), arrivals, control,
                            external_period=1)
    executor.add_node(served.node)
    yield served, arrivals, executor
    executor.remove_node(served.node)
    served.destroy()


def test_node_parameters_over_the_standard_services(parameters, ros_node):
    from rclpy.parameter_client import AsyncParameterClient

    served, arrivals, executor = parameters
    node, _ = ros_node
    client = AsyncParameterClient(node, "control")
    assert client.wait_for_services(timeout_sec=10)

    def wait(future):
        executor.spin_until_future_complete(future, timeout_sec=10)
        return future.result()

    names = wait(client.list_parameters()).result.names
    assert {"max_speed", "resolution", "frame_id"} <= set(names)
    described = {d.name: d for d in wait(client.describe_parameters(
        ["max_speed", "resolution"])).descriptors}
    assert not described["max_speed"].read_only and described["resolution"].read_only
    assert described["max_speed"].additional_constraints == "> 0"

    results = wait(client.set_parameters([Parameter("max_speed", value=-1.0),
                                          Parameter("resolution", value=0.1),
                                          Parameter("max_speed", value=0.3),
                                          Parameter("lookahead", value=0.8)])).results
    assert not results[0].successful and "control.max_speed" in results[0].reason
    assert "greater than 0" in results[0].reason
    assert not results[1].successful and "read-only" in results[1].reason
    assert results[2].successful and results[3].successful
    carried = arrivals.take(0)["/cosim/params/control"]
    assert changes_in(carried) == {"max_speed": 0.3, "lookahead": 0.8}  # every change so far
    values = wait(client.get_parameters(["max_speed"])).values
    assert values[0].double_value == 0.3

    served.reset()  # the run was reset: the scenario's values again, nothing carried
    assert wait(client.get_parameters(["max_speed"])).values[0].double_value == 0.5
    assert arrivals.take(0) == {}


def test_parameters_are_fixed_when_the_scenario_is_not_interactive(ros_node):
    from nodes.registry import load_class
    from orchestrator.ros_surface.param_server import NodeParameters

    node, _ = ros_node
    scenario = load_scenario(NAV)
    plan = scenario.nodes["control"]
    served = NodeParameters(node.context, plan, load_class(plan.class_ref), None,
                            RunControl(scenario.tick_ns), external_period=1)
    try:
        result = served.node.set_parameters([Parameter("max_speed", value=0.3)])[0]
        assert not result.successful and "interactive: true" in result.reason
        assert served.node.get_parameter("max_speed").value == 0.5
    finally:
        served.destroy()
