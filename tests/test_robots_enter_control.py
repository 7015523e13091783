"""Robots that enter and leave a swarm whose controller managers run in the physics step
(issue 49 item 1: a robot that enters gets "its lidar, its controller, its controller
manager"). tests/scenarios/swarm_enter_control.yaml: swarm_urdf_control's xacro robots with
robots.controllers; robot_0 and robot_1 from the start, ``gone`` in at 0.4 s (tick 20) and
out at 1.2 s (tick 60), ``late`` in at 1 s (tick 50), driven to its goal through its own
diff_drive_controller.

At a robot's enter tick physics recompiles the world, rebinds every robot's MujocoSystem to
the new model's joint and actuator addresses (their controllers keep their state) and builds
the new robot's manager, whose controllers activate at that tick; at its delete the manager
goes with the robot. Its controllers' topics live only in its window.
"""

from __future__ import annotations

import threading
from types import SimpleNamespace

import pytest
from controller_manager_msgs.srv import (
    ListControllers,
    ListHardwareInterfaces,
    LoadController,
    SwitchController,
)

from descriptions.load import load_scenario
from orchestrator.api import run
from tests.helpers import ROOT

SCENARIO = ROOT / "tests" / "scenarios" / "swarm_enter_control.yaml"
S = 1_000_000_000
DDC = "diff_drive_controller"
FROM_START = ("robot_0", "robot_1")


@pytest.fixture(scope="module")
def entered(tmp_path_factory):
    """The scenario over 4 s in-process."""
    return run(SCENARIO, in_process=True, out=tmp_path_factory.mktemp("runs"), duration="4s",
               picture=False)


def test_a_robot_that_enters_reaches_its_goal_through_its_own_diff_drive_controller(entered):
    metrics = entered.metrics
    assert metrics["late/arrived"] == 1.0 and 1.0 < metrics["late/time_to_goal"] < 4.0
    assert metrics[f"late/controller_manager/active:{DDC}"] == 1.0
    assert metrics["collisions"] == 0
    # its manager went with the deleted robot
    assert not any(k.startswith("gone/") for k in metrics)
    # the controller's topics only while the robot is in the run: its odometry from the
    # enter tick (the wheels' own frame: it starts at 0), its commands from its controller
    odom = list(entered.messages(f"/late/{DDC}/odom"))
    assert odom[0][0] == 1 * S and odom[0][1].pose.pose.position.x == 0.0
    assert odom[-1][1].pose.pose.position.x > 1.0  # driven by its wheels to the goal
    assert min(t for t, _ in entered.messages(f"/late/{DDC}/cmd_vel")) >= 1 * S
    gone = [t for t, _ in entered.messages(f"/gone/{DDC}/odom")]
    assert gone[0] == int(0.4 * S) and gone[-1] < int(1.2 * S) and len(gone) == 40
    assert "/late/cmd_vel" not in entered.topics()  # physics' own drive stands aside
    # what clients send its manager (the external node's) only while it is in the run too
    switch = [t for t, _ in entered.messages("/gone/controller_manager/cosim/switch")]
    assert switch[0] == int(0.4 * S) and switch[-1] < int(1.2 * S) and len(switch) == 40


def test_the_robots_there_from_the_start_drive_as_without_the_events(entered, tmp_path):
    """Up to late's enter tick (gone entered before it), bit for bit: a robot entering
    rebinds the others' hardware to the recompiled world and changes nothing of theirs."""
    alone = run(load_scenario(SCENARIO, {"events": []}), in_process=True, out=tmp_path,
                duration="1s", picture=False)
    for robot in FROM_START:
        for topic in (f"/{robot}/odom", f"/{robot}/{DDC}/odom"):
            reference = list(alone.messages(topic))
            assert len(reference) == 51
            assert list(entered.messages(topic))[:51] == reference, topic


def test_one_digest_in_process_and_multi_process(tmp_path):
    """Independent runs of the same 2 s (both robots enter, one leaves)."""
    reference = run(SCENARIO, in_process=True, out=tmp_path, duration="2s", picture=False)
    separate = run(SCENARIO, out=tmp_path, duration="2s", picture=False)
    assert separate.digest == reference.digest


class _Node:
    """Where a controller manager server makes its services: kept by name."""

    def __init__(self):
        self.services = {}

    def create_service(self, srv, name, handler, callback_group=None):
        self.services[name] = (srv, handler)

    def create_subscription(self, *args, **kwargs):
        pass


def test_a_robots_manager_answers_only_while_it_is_in_the_run(entered):
    """A robot's manager services (orchestrator.ros_surface.controller_manager) follow
    physics' metrics: before late enters and after gone leaves they list nothing and
    refuse; while late is in they list its controller and its hardware."""
    from orchestrator.ros_surface.controller_manager import controller_managers
    from orchestrator.ros_surface.simcontrol import RunControl
    from runtime.arrivals import Arrivals

    scenario = load_scenario(SCENARIO)
    external = scenario.nodes["external"]
    arrivals = Arrivals(external.outputs)
    control = RunControl(scenario.tick_ns)
    node = _Node()
    servers = {s.robot: s for s in controller_managers(node, None, scenario, control,
                                                       arrivals, lambda h: h)}
    assert set(servers) == {*FROM_START, "gone", "late"}

    def call(robot, verb, srv, **fields):
        _, handler = node.services[f"/{robot}/controller_manager/{verb}"]
        return handler(srv.Request(**fields), srv.Response())

    def listed(robot):
        return {c.name: c.state for c in call(robot, "list_controllers",
                                              ListControllers).controller}

    assert listed("robot_0") == {DDC: "active"} and listed("late") == {}
    refused = call("late", "switch_controller", SwitchController,
                   deactivate_controllers=[DDC])
    assert not refused.ok and "'late' is not in the run" in refused.message
    assert not call("late", "load_controller", LoadController, name=DDC).ok
    assert not arrivals.count  # nothing entered the run
    # at the end of the run: late is in, gone has left (physics' metrics say so)
    physics = SimpleNamespace(metrics=entered.outcome.result.metrics["physics"])
    for observe in control.observers:
        observe(200, {"physics": physics})
    assert listed("late") == {DDC: "active"} and listed("gone") == {}
    interfaces = call("late", "list_hardware_interfaces", ListHardwareInterfaces)
    assert {i.name for i in interfaces.command_interfaces} == {
        "wheel_left_joint/velocity", "wheel_right_joint/velocity"}
    assert not call("gone", "switch_controller", SwitchController,
                    deactivate_controllers=[DDC]).ok
    # a switch of late's that is waiting when late leaves is answered: it never entered
    answer = {}
    waiting = threading.Thread(target=lambda: answer.update(done=call(
        "late", "switch_controller", SwitchController, deactivate_controllers=[DDC])))
    waiting.start()
    while not arrivals.count:
        waiting.join(0.01)
    left = {k: v for k, v in physics.metrics.items() if not k.startswith("late/")}
    for observe in control.observers:
        observe(201, {"physics": SimpleNamespace(metrics=left)})
    waiting.join(10)
    assert not answer["done"].ok and "left the run" in answer["done"].message
