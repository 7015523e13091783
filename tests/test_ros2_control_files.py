"""The controllers file read as ros2_control reads it, once: one reading per file content
(an edited file is read again), several files merged in order as ros2_control_node merges
its ``--params-file`` files; and named, as gz_ros2_control users name it, by the
``<parameters>`` of the description's ros2_control plugin tag."""

from __future__ import annotations

import os
import shutil

import pytest
import yaml

from descriptions.load import load_scenario
from nodes.ros2_control.config import read_controllers_file
from plan.errors import ScenarioError
from tests.helpers import ROOT

JTC = "joint_trajectory_controller/JointTrajectoryController"
JSB = "joint_state_broadcaster/JointStateBroadcaster"


def write(path, doc: dict):
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def manager(rate: int, **controllers: str) -> dict:
    return {"controller_manager": {"ros__parameters": {
        "update_rate": rate, **{n: {"type": t} for n, t in controllers.items()}}}}


def jtc(*joints: str, **more) -> dict:
    return {"jtc": {"ros__parameters": {"joints": list(joints),
                                        "command_interfaces": ["position"],
                                        "state_interfaces": ["position", "velocity"],
                                        **more}}}


def test_a_file_is_read_once_per_content_and_again_when_edited(tmp_path):
    path = write(tmp_path / "c.yaml", {**manager(50, jtc=JTC), **jtc("a", "b")})
    first = read_controllers_file(path)
    assert read_controllers_file(str(path)) is first  # the same reading, not a new one
    stat = path.stat()
    write(path, {**manager(25, jtc=JTC), **jtc("a", "b")})  # same size, maybe same mtime
    os.utime(path, ns=(stat.st_atime_ns, stat.st_mtime_ns))
    again = read_controllers_file(path)
    assert again is not first and again.update_rate == 25


def test_several_files_merge_in_order_a_later_parameter_over_an_earlier(tmp_path):
    base = write(tmp_path / "base.yaml", {**manager(50, jtc=JTC), **jtc("a", "b")})
    extra = write(tmp_path / "extra.yaml", {
        "controller_manager": {"ros__parameters": {"update_rate": 100, "jsb": {"type": JSB}}},
        **jtc("c", "d")})
    merged = read_controllers_file(base, extra)
    assert merged.update_rate == 100
    assert [c.name for c in merged.controllers] == ["jtc", "jsb"]
    assert merged.named("jtc").params.joints == ["c", "d"]
    assert read_controllers_file(base).named("jtc").params.joints == ["a", "b"]


def test_a_nodes_own_block_wins_over_any_files_wildcard_as_rclcpp_resolves(tmp_path):
    """rclcpp applies the merged ``/**`` block before the node's own, whatever the files'
    order: a later file's ``/**`` does not override an earlier file's node block."""
    first = write(tmp_path / "first.yaml", {
        "/**": {"ros__parameters": {"allow_partial_joints_goal": False}},
        **manager(50, jtc=JTC), **jtc("a", "b", allow_partial_joints_goal=True)})
    later = write(tmp_path / "later.yaml", {
        "/**": {"ros__parameters": {"allow_partial_joints_goal": False,
                                    "allow_nonzero_velocity_at_trajectory_end": True}},
        **jtc("c", "d")})
    merged = read_controllers_file(first, later).named("jtc").params
    assert merged.allow_partial_joints_goal is True  # first's own block over later's /**
    assert merged.joints == ["c", "d"] and merged.allow_nonzero_velocity_at_trajectory_end is True
    alone = write(tmp_path / "alone.yaml", {**manager(50, jtc=JTC), **jtc("a", "b"),
                                            "/**": {"ros__parameters": {
                                                "allow_partial_joints_goal": True}}})
    assert read_controllers_file(alone).named("jtc").params.allow_partial_joints_goal is True


# The Gazebo-style tag: a description written for gz_ros2_control names its controllers
# file in its plugin's <parameters>, and cosim reads it as robots.controllers.

SWARM = ROOT / "scenarios" / "swarm_urdf_control.yaml"
PLUGIN = ('<gazebo><plugin filename="gz_ros2_control-system" '
          'name="gz_ros2_control::GazeboSimROS2ControlPlugin">{}</plugin></gazebo>')


def tagged_swarm(tmp_path, *parameters: str, controllers: str | bool | None = None,
                 name: str = "swarm"):
    """swarm_urdf_control.yaml (as ``name``.yaml) over a copy of mybot_description whose
    xacro carries the gz_ros2_control plugin tag with these ``<parameters>`` (made once in
    ``tmp_path``), without robots.controllers (or with ``controllers``); its path."""
    package = tmp_path / "mybot_description"
    if not package.exists():
        shutil.copytree(SWARM.parent / "robots" / "mybot_description", package)
        shutil.copy(SWARM.parent / "controllers" / "swarm_mybot_controllers.yaml",
                    package / "config")
        xacro = package / "urdf" / "mybot.urdf.xacro"
        tag = PLUGIN.format("".join(f"<parameters>{p}</parameters>" for p in parameters))
        xacro.write_text(xacro.read_text().replace("</robot>", f"  {tag}\n</robot>"))
    doc = yaml.safe_load(SWARM.read_text())
    doc["world"] = str(SWARM.parent / doc["world"])
    doc["duration"] = "1s"
    robots = doc["robots"]
    robots["description"] = "mybot_description/urdf/mybot.urdf.xacro"
    robots["urdf"]["packages"] = {"mybot_description": "mybot_description"}
    robots.pop("controllers")
    if controllers is not None:
        robots["controllers"] = controllers
    return write(tmp_path / f"{name}.yaml", doc)


FILE = "$(find mybot_description)/config/swarm_mybot_controllers.yaml"


def test_the_plugin_tags_parameters_give_every_robot_its_manager_as_robots_controllers(
        tmp_path):
    from orchestrator.api import run

    tagged = tagged_swarm(tmp_path, FILE, name="tag")
    scenario = load_scenario(tagged)
    graph = {i.graph_topic: i.producer for i in scenario.nodes["physics"].inputs}
    assert graph["/robot_2/diff_drive_controller/cmd_vel"] == "control@robot_2"
    assert not scenario.warnings
    named = tagged_swarm(tmp_path, FILE, name="key", controllers=(
        "mybot_description/config/swarm_mybot_controllers.yaml"))
    assert not load_scenario(named).warnings  # both name the same file: nothing to say
    runs = [run(s, in_process=True, out=tmp_path / s.stem, picture=False)
            for s in (tagged, named)]
    metrics = runs[0].outcome.result.metrics["physics"]
    assert metrics["robot_2/controller_manager/active:diff_drive_controller"] == 1.0
    assert runs[0].digest == runs[1].digest


def test_robots_controllers_wins_over_the_tag_and_says_so_where_they_differ(tmp_path):
    scenario = load_scenario(tagged_swarm(
        tmp_path, FILE, controllers=str(SWARM.parent / "controllers" /
                                        "swarm_mybot_controllers.yaml")))
    (notice,) = [w for w in scenario.warnings if "plugin tag" in w]
    assert notice.key == "robots.controllers" and "is used instead" in notice


def test_a_tag_naming_a_missing_file_is_exit_2_naming_the_description_and_the_tag(tmp_path):
    path = tagged_swarm(tmp_path, "$(find mybot_description)/config/missing.yaml")
    with pytest.raises(ScenarioError) as raised:
        load_scenario(path)
    text = str(raised.value)
    assert raised.value.key == "robots.description"
    assert "mybot.urdf.xacro" in text and "<parameters>" in text
    assert str(tmp_path / "mybot_description" / "config" / "missing.yaml") in text
    assert "robots.controllers" in text  # the fix names the other way


def test_robots_controllers_false_leaves_the_tag_alone(tmp_path):
    path = tagged_swarm(tmp_path, "$(find mybot_description)/config/missing.yaml",
                        controllers=False)
    scenario = load_scenario(path)  # the missing file is not read: no manager at all
    physics = scenario.nodes["physics"]
    assert physics.params.controller_manager is None
    assert not any("controller" in i.graph_topic for i in physics.inputs)
    assert not any("controller" in t for t in physics.outputs)


def test_several_parameters_tags_merge_in_order_and_package_uris_resolve(tmp_path):
    from nodes.ros2_control.node import read

    later = tmp_path / "mybot_description" / "config" / "slower.yaml"
    path = tagged_swarm(tmp_path, "package://mybot_description/config/"
                        "swarm_mybot_controllers.yaml", "$(find mybot_description)/config/"
                        "slower.yaml")
    write(later, {"/**/controller_manager": {"ros__parameters": {"update_rate": 25}}})
    manager = load_scenario(path).nodes["physics"].params.controller_manager
    assert manager.controllers == [str(later.parent / "swarm_mybot_controllers.yaml"),
                                   str(later)]
    assert read(manager).update_rate == 25
    assert [c.name for c in read(manager).controllers] == ["diff_drive_controller"]
