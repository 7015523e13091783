"""A robot's controller manager folded into the physics node by the plan
(plan/hardware_wiring.py): its topics are physics', no topic runs between controllers and
hardware, a file that still wires the old hardware topics resolves the same with notices,
and what cannot run in physics' step is refused naming the node."""

from __future__ import annotations

from pathlib import Path

import pytest

from descriptions.load import load_scenario
from plan.errors import ScenarioError

SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios"


def _wiring(scenario) -> dict[str, list[tuple[str, str, str]]]:
    """node -> its inputs as (own topic, graph topic, producer)."""
    return {name: sorted((i.topic, i.graph_topic, i.producer) for i in plan.inputs)
            for name, plan in scenario.nodes.items()}


def _copy(tmp_path: Path, name: str, text: str) -> Path:
    """``text`` as scenario ``name`` beside links to the scenarios' folders."""
    for folder in ("controllers", "worlds", "robots"):
        (tmp_path / folder).symlink_to(SCENARIOS / folder)
    path = tmp_path / name
    path.write_text(text)
    return path


def test_a_manager_runs_in_physics_and_its_controllers_topics_are_physics():
    scenario = load_scenario(SCENARIOS / "arm_control.yaml")
    assert "controller_manager" not in scenario.nodes  # folded into physics
    physics = scenario.nodes["physics"]
    assert physics.params.controller_manager.name == "controller_manager"
    # the broadcaster's /joint_states is the robot's; the trajectory controller's state
    assert physics.output_names["/joint_states"] == "/joint_states"
    assert "/joint_trajectory_controller/controller_state" in physics.outputs
    # the forward controller's ~/commands (remapped to /joint_commands) is physics' input,
    # delayed; physics' own /joint_commands gives way to the controllers
    wiring = {i.topic: (i.graph_topic, i.producer, i.mode) for i in physics.inputs}
    assert wiring["/forward_position_controller/commands"] == ("/joint_commands", "arm",
                                                                "delayed")
    assert "/joint_commands" not in wiring
    topics = {t for plan in scenario.nodes.values() for t in plan.outputs}
    assert not [t for t in topics if t.startswith("/cosim/hardware") or t ==
                "/cosim/base_command"]


def test_a_robots_manager_takes_its_controllers_topics_under_its_namespace():
    scenario = load_scenario(SCENARIOS / "swarm_urdf_control.yaml")
    physics = scenario.nodes["physics"]
    assert not [n for n in scenario.nodes if n.startswith("controller_manager")]
    wiring = {i.topic: (i.graph_topic, i.producer) for i in physics.inputs}
    assert wiring["/robot_2/diff_drive_controller/cmd_vel"] == (
        "/robot_2/diff_drive_controller/cmd_vel", "control@robot_2")
    assert wiring["/robot_2/controller_manager/cosim/switch"][1] == "external"
    assert "/robot_2/cmd_vel" not in wiring  # the diff drive controller drives the wheels
    assert "/robot_2/diff_drive_controller/odom" in physics.outputs


def test_a_scenario_wired_by_hand_resolves_as_before(tmp_path):
    text = (SCENARIOS / "arm_control.yaml").read_text()
    by_hand = text.replace(
        "      imu: null\n", "      imu: null\n    remap: {/joint_states: /cosim/hardware_states,"
        " /joint_commands: /cosim/hardware_commands}\n    inputs:\n      - {topic: "
        "/joint_commands, mode: delayed}\n", 1)
    assert by_hand != text
    path = _copy(tmp_path, "arm_control.yaml", by_hand)
    scenario = load_scenario(path)
    assert _wiring(scenario) == _wiring(load_scenario(SCENARIOS / "arm_control.yaml"))
    said = [w for w in scenario.warnings if "physics node's step" in w.problem
            or "controllers command" in w.problem]
    assert [w.key for w in said] == ["nodes[0] (physics).remap./joint_states",
                                     "nodes[0] (physics).remap./joint_commands",
                                     "nodes[0] (physics).inputs[0]"]
    assert "delete the remaps and inputs naming /cosim/hardware_*" in said[0].accepted
    assert not load_scenario(SCENARIOS / "arm_control.yaml").warnings


def test_a_broadcaster_per_robot_publishes_each_robots_joint_states(tmp_path):
    controllers = tmp_path / "with_broadcaster.yaml"
    own = (SCENARIOS / "robots/mybot_description/config/mybot_controllers.yaml").read_text()
    controllers.write_text(own.replace(
        "    diff_drive_controller:\n      type:", "    joint_state_broadcaster:\n      type: "
        "joint_state_broadcaster/JointStateBroadcaster\n\n    diff_drive_controller:\n"
        "      type:", 1))
    text = (SCENARIOS / "swarm_urdf_control.yaml").read_text().replace(
        "controllers/swarm_mybot_controllers.yaml", "with_broadcaster.yaml")
    scenario = load_scenario(_copy(tmp_path, "swarm.yaml", text))
    physics = scenario.nodes["physics"]
    assert physics.output_names["/robot_3/joint_states"] == "/robot_3/joint_states"
    assert "/robot_3/dynamic_joint_states" in physics.outputs


def test_a_manager_at_another_rate_than_physics_is_refused_naming_the_node(tmp_path):
    text = (SCENARIOS / "nav_control.yaml").read_text()
    slow = text.replace("    rate: 50\n    params:\n      start:", "    rate: 25\n"
                        "    params:\n      start:", 1)  # physics below update_rate 50
    assert slow != text
    with pytest.raises(ScenarioError) as err:
        load_scenario(_copy(tmp_path, "nav_control.yaml", slow))
    assert err.value.key == "nodes[3] (controller_manager).rate"
    assert "physics node's step" in err.value.problem


def _one_line(text: str) -> str:
    """nav_urdf_control's text with its controller manager node given as
    robots.controllers."""
    text = text[:text.index("  - name: controller_manager")]
    return text.replace("  position_tolerance:", "  controllers: robots/mybot_description/"
                        "config/mybot_controllers.yaml\n  position_tolerance:", 1)


def test_robots_controllers_is_the_per_robot_manager_node(tmp_path):
    text = (SCENARIOS / "nav_urdf_control.yaml").read_text()
    one_line = load_scenario(_copy(tmp_path, "one_line.yaml", _one_line(text)))
    written = load_scenario(SCENARIOS / "nav_urdf_control.yaml")
    assert "controller_manager" not in _one_line(text).split("nodes:")[1]
    assert _wiring(one_line) == _wiring(written)
    assert {n: p.output_names for n, p in one_line.nodes.items()} == {
        n: p.output_names for n, p in written.nodes.items()}
    assert one_line.nodes["physics"].params == written.nodes["physics"].params
    assert written.nodes["physics"].params.controller_manager is not None


@pytest.mark.parametrize("change, problem", [
    (lambda t: _one_line(t).replace("mybot_controllers.yaml", "missing.yaml"), "missing.yaml"),
    (lambda t: t.replace("  position_tolerance:", "  controllers: robots/mybot_description/"
                         "config/mybot_controllers.yaml\n  position_tolerance:", 1),
     "also has a node named controller_manager"),
])
def test_robots_controllers_refused_naming_the_key(tmp_path, change, problem):
    text = change((SCENARIOS / "nav_urdf_control.yaml").read_text())
    with pytest.raises(ScenarioError) as err:
        load_scenario(_copy(tmp_path, "bad.yaml", text))
    assert err.value.key == "robots.controllers"
    assert problem in err.value.problem


def test_an_update_rate_other_than_physics_rate_over_n_names_the_file_key_and_rates():
    ur = SCENARIOS.parent / "tests" / "scenarios" / "ur5e_control.yaml"
    state = "/joint_trajectory_controller/controller_state"
    slow = load_scenario(ur, {"nodes.physics.rate": 500})  # update_rate 100: 500 / 5
    assert slow.schedule.topic_period("physics", state) == 5 * slow.schedule.periods["physics"]
    with pytest.raises(ScenarioError) as err:
        load_scenario(ur, {"nodes.physics.rate": 50})  # 50 / 100: above physics' rate
    text = str(err.value)
    assert "robots.controllers" in text
    assert "ur_controllers.yaml: controller_manager.ros__parameters.update_rate" in text
    assert "(100 Hz," in text and "(50 Hz, nodes[0] (physics).rate)" in text
    assert "update_rate: one of 50, 25, 10, 5, 2, 1 Hz in" in text
    assert "physics' rate: a whole multiple of 100" in text


def test_an_inactive_controller_publishes_nothing_where_no_node_of_the_run_takes_its_topics(
        tmp_path):
    """As upstream: the trajectory controller of arm_control is loaded and never activated;
    its ~/controller_state is in no node's inputs, so the run records none of it (the empty
    message its step gives stands for nothing), while a node that takes it gets one at each
    tick (lockstep waits for it)."""
    from orchestrator import api

    state = "/joint_trajectory_controller/controller_state"
    scenario = load_scenario(SCENARIOS / "arm_control.yaml")
    assert state in scenario.nodes["physics"].unconsumed
    assert "/joint_states" not in scenario.nodes["physics"].unconsumed  # the arm takes it
    run = api.run(SCENARIOS / "arm_control.yaml", out=tmp_path / "runs", duration="1s",
                  in_process=True, picture=False)
    assert state not in run.manifest["topic_digests"]
    assert "/dynamic_joint_states" in run.manifest["topic_digests"]
    text = (SCENARIOS / "arm_control.yaml").read_text().replace(
        "nodes:\n", "nodes:\n  - name: taker\n    module: nodes.testing:TakerNode\n"
        "    rate: 10\n    params: {output: /taken}\n"
        f"    inputs: [{{topic: {state}, mode: delayed}}]\n", 1)
    taken = load_scenario(_copy(tmp_path, "taken.yaml", text))
    assert state not in taken.nodes["physics"].unconsumed
    run = api.run(tmp_path / "taken.yaml", out=tmp_path / "runs", duration="1s",
                  in_process=True, picture=False)
    assert state in run.manifest["topic_digests"]
