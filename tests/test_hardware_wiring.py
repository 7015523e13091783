"""Physics wired to a robot's controller manager by the plan (plan/hardware_wiring.py): no
scenario remaps cosim's hardware topics, a file that still does resolves the same, and what
cannot be wired is refused naming the node."""

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


def test_a_manager_with_a_broadcaster_takes_physics_joint_topics():
    scenario = load_scenario(SCENARIOS / "arm_control.yaml")
    physics = scenario.nodes["physics"].output_names
    assert physics["/joint_states"] == "/cosim/hardware_states"
    assert scenario.nodes["controller_manager"].output_names["/joint_states"] == "/joint_states"
    assert ("/cosim/hardware_states", "/cosim/hardware_states", "physics") in _wiring(
        scenario)["controller_manager"]
    assert ("/joint_commands", "/cosim/hardware_commands", "controller_manager") in _wiring(
        scenario)["physics"]


def test_a_robots_manager_reads_and_writes_physics_own_topics():
    scenario = load_scenario(SCENARIOS / "nav_urdf_control.yaml")
    manager = scenario.nodes["controller_manager@mybot"]
    assert manager.output_names["/cosim/base_command"] == "/mybot/cmd_vel"
    assert ("/cosim/hardware_states", "/mybot/joint_states", "physics") in _wiring(
        scenario)["controller_manager@mybot"]
    assert scenario.nodes["physics"].output_names["/mybot/joint_states"] == "/mybot/joint_states"


def test_a_scenario_wired_by_hand_resolves_as_before(tmp_path):
    text = (SCENARIOS / "arm_control.yaml").read_text()
    by_hand = text.replace(
        "      imu: null\n", "      imu: null\n    remap: {/joint_states: /cosim/hardware_states,"
        " /joint_commands: /cosim/hardware_commands}\n", 1)
    assert by_hand != text
    path = _copy(tmp_path, "arm_control.yaml", by_hand)
    scenario = load_scenario(path)
    assert _wiring(scenario) == _wiring(load_scenario(SCENARIOS / "arm_control.yaml"))
    said = [w for w in scenario.warnings if "by hand" in w]
    assert [w.key for w in said] == ["nodes[0] (physics).remap./joint_states",
                                     "nodes[0] (physics).remap./joint_commands"]
    assert "delete the remaps naming /cosim/ topics" in said[0].accepted
    assert not [w for w in load_scenario(SCENARIOS / "arm_control.yaml").warnings
                if "by hand" in w]


def test_a_broadcaster_per_robot_is_refused_naming_the_node(tmp_path):
    controllers = tmp_path / "with_broadcaster.yaml"
    own = (SCENARIOS / "robots/mybot_description/config/mybot_controllers.yaml").read_text()
    controllers.write_text(own.replace(
        "    diff_drive_controller:\n      type:", "    joint_state_broadcaster:\n      type: "
        "joint_state_broadcaster/JointStateBroadcaster\n\n    diff_drive_controller:\n"
        "      type:", 1))
    text = (SCENARIOS / "nav_urdf_control.yaml").read_text().replace(
        "robots/mybot_description/config/mybot_controllers.yaml", "with_broadcaster.yaml")
    with pytest.raises(ScenarioError) as err:
        load_scenario(_copy(tmp_path, "nav_urdf_control.yaml", text))
    assert "(controller_manager)" in err.value.key
    assert "/joint_states" in err.value.problem and "robots: section" in err.value.problem


def _one_line(text: str) -> str:
    """nav_urdf_control's text with its controller manager node given as robots.controllers
    and physics listing no input (its /cmd_vel is the manager's)."""
    manager = text.index("  - name: controller_manager")
    physics_input = "    inputs:\n      - {topic: /cmd_vel, mode: delayed}\n"
    assert text.count(physics_input) == 1
    text = text[:manager].replace(physics_input, "")
    return text.replace("  position_tolerance:", "  controllers: robots/mybot_description/"
                        "config/mybot_controllers.yaml\n  position_tolerance:", 1)


def test_robots_controllers_is_the_per_robot_manager_node(tmp_path):
    text = (SCENARIOS / "nav_urdf_control.yaml").read_text()
    one_line = load_scenario(_copy(tmp_path, "one_line.yaml", _one_line(text)))
    written = load_scenario(SCENARIOS / "nav_urdf_control.yaml")
    assert "controller_manager" not in _one_line(text).split("nodes:")[1]
    for scenario in (one_line, written):
        manager = scenario.nodes["controller_manager@mybot"]
        assert manager.period_ticks * scenario.tick_ns == 20_000_000  # update_rate: 50
    assert _wiring(one_line) == _wiring(written)
    assert {n: p.output_names for n, p in one_line.nodes.items()} == {
        n: p.output_names for n, p in written.nodes.items()}
    assert one_line.nodes["controller_manager@mybot"].params == \
        written.nodes["controller_manager@mybot"].params


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
