"""One robot as ROS users expect one robot (issue 47 item 5): a lone robot of a ``robots:``
section lives at the root, as robot_state_publisher and a one-robot Gazebo world publish it
(/cmd_vel, /odom, /scan, /joint_states, /robot_description; TF frames odom, base_link
without a prefix; joint names as the description names them); the same robot with a
namespace named in its entry is under it (topics and frames); two robots are namespaced by
their names. Each case is checked on the plan and on the first activation of physics and of
the robot's lidar, in-process (no run: the transports carry what these publish)."""

from __future__ import annotations

import pytest
import yaml

from descriptions.load import load_scenario
from nodes.contract import Tick
from plan.errors import ScenarioError
from plan.robots import ros_identity
from runtime.build import make_node
from tests.helpers import ROOT

NAV_URDF = ROOT / "scenarios" / "nav_urdf.yaml"
TOPICS = ("/cmd_vel", "/odom", "/scan", "/joint_states", "/robot_description", "/imu", "/plan")


def two_robots(tmp_path, namespace: str | None = None):
    """nav_urdf with a second robot beside mybot (``namespace``: mybot's, if given)."""
    doc = yaml.safe_load(NAV_URDF.read_text())
    doc["world"] = str((NAV_URDF.parent / doc["world"]).resolve())
    robots = doc["robots"]
    robots["description"] = str(NAV_URDF.parent / robots["description"])
    robots["urdf"]["packages"] = {k: str((NAV_URDF.parent / v).resolve())
                                  for k, v in robots["urdf"]["packages"].items()}
    robots["named"].append({"name": "other", "start": {"x": -3.0, "y": 3.0, "yaw": 0.0},
                            "goal": {"x": 3.0, "y": -3.0}})
    if namespace is not None:
        robots["named"][0]["namespace"] = namespace
    path = tmp_path / "two.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def first_activation(scenario, robot: str = "mybot"):
    """What physics and the robot's lidar publish at tick 0."""
    physics = make_node(scenario, "physics").step(Tick(0, 0), {})
    lidar = make_node(scenario, f"lidar@{robot}")
    scan = lidar.step(Tick(0, 0), {"/cosim/world_state": physics["/cosim/world_state"]})
    return physics, scan


def frames(physics) -> set[tuple[str, str]]:
    return {(t.header.frame_id, t.child_frame_id)
            for key in ("/tf", "/tf_static") for t in physics[key].transforms}


@pytest.mark.parametrize("namespace", ["", "rover"])
def test_a_lone_robot_is_at_the_root_unless_its_entry_names_a_namespace(namespace):
    overrides = {"robots.named.mybot.namespace": namespace} if namespace else {}
    scenario = load_scenario(NAV_URDF, overrides)
    ns, fp = (f"/{namespace}", f"{namespace}/") if namespace else ("", "")
    assert {ns + t for t in TOPICS} <= set(scenario.topics)
    assert not any(t.startswith("/mybot") for t in scenario.topics)  # its name is no namespace
    assert scenario.nodes["control@mybot"].output_names["/cmd_vel"] == f"{ns}/cmd_vel"
    assert ros_identity("control@mybot", scenario.robots.namespace_of("mybot")) == (
        "control", ns or "/")
    physics, scan = first_activation(scenario)
    assert {f"{ns}/odom", f"{ns}/joint_states", f"{ns}/robot_description"} <= set(physics)
    assert {("map", f"{fp}odom"), (f"{fp}odom", f"{fp}base_footprint"),
            (f"{fp}base_link", f"{fp}base_scan"),
            (f"{fp}base_link", f"{fp}wheel_left_link")} <= frames(physics)
    assert physics[f"{ns}/joint_states"].name == ["wheel_left_joint", "wheel_right_joint"]
    odom = physics[f"{ns}/odom"]
    assert (odom.header.frame_id, odom.child_frame_id) == (f"{fp}odom", f"{fp}base_footprint")
    assert scan["/scan"].header.frame_id == f"{fp}base_scan"  # remapped by the plan


def test_two_robots_are_each_under_their_namespace(tmp_path):
    scenario = load_scenario(two_robots(tmp_path))
    for robot in ("mybot", "other"):
        assert {f"/{robot}{t}" for t in TOPICS} <= set(scenario.topics)
    assert not {"/cmd_vel", "/odom", "/joint_states"} & set(scenario.topics)
    physics, scan = first_activation(scenario, "other")
    assert {("other/odom", "other/base_footprint"), ("mybot/base_link", "mybot/base_scan"),
            ("other/base_link", "other/wheel_left_link")} <= frames(physics)
    assert physics["/other/joint_states"].name == ["wheel_left_joint", "wheel_right_joint"]
    assert scan["/scan"].header.frame_id == "other/base_scan"


def test_two_robots_in_one_namespace_are_refused_at_the_key_that_gives_it(tmp_path):
    # mybot's entry says namespace: other; robot 'other' has none (its name is its namespace)
    with pytest.raises(ScenarioError, match="share the namespace 'other'") as err:
        load_scenario(two_robots(tmp_path, namespace="other"))
    assert err.value.key == "robots.named[0].namespace"
    # the second entry says namespace: mybot, the first robot's by its name
    with pytest.raises(ScenarioError, match="share the namespace 'mybot'") as err:
        load_scenario(two_robots(tmp_path), {"robots.named.other.namespace": "mybot"})
    assert err.value.key == "robots.named[1].namespace"


def mjcf_swarm_with_controllers(tmp_path, namespace: str = "alpha"):
    """swarm.yaml cut to two MJCF robots, each with a hosted controller manager (nav_control's
    diff drive, its blocks under /**), the first in ``namespace``."""
    swarm = ROOT / "scenarios" / "swarm.yaml"
    doc = yaml.safe_load(swarm.read_text())
    doc["world"] = str((swarm.parent / doc["world"]).resolve())
    robots = doc["robots"]
    robots["description"] = str((swarm.parent / robots["description"]).resolve())
    robots["named"] = robots["named"][:2]
    robots["named"][0]["namespace"] = namespace
    controllers = yaml.safe_load((swarm.parent / "controllers" / "nav_controllers.yaml")
                                 .read_text())
    (tmp_path / "controllers.yaml").write_text(yaml.safe_dump(
        {f"/**/{key}": block for key, block in controllers.items()}))
    robots["controllers"] = str(tmp_path / "controllers.yaml")
    physics, control = doc["nodes"][0], doc["nodes"][2]
    physics.pop("inputs")  # the managers' cmd_vel, not physics' own
    control.update(params={"enable_stamped_cmd_vel": True},
                   remap={"/cmd_vel": "/diff_drive_controller/cmd_vel"})
    path = tmp_path / "swarm_control.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def test_an_mjcf_robots_controllers_find_its_joints_in_a_namespace_not_its_name(tmp_path):
    # the hardware's joints are MuJoCo's less 'robot_0/', not the frames ('alpha/...')
    scenario = load_scenario(mjcf_swarm_with_controllers(tmp_path))
    physics = make_node(scenario, "physics")
    out = physics.step(Tick(0, 0), {})
    assert {"/alpha/diff_drive_controller/odom", "/robot_1/diff_drive_controller/odom"} <= set(
        out)
    metrics = physics.metrics()
    for robot in ("robot_0", "robot_1"):
        assert metrics[f"{robot}/controller_manager/active:diff_drive_controller"] == 1.0
    # each diff drive's odometry in its robot's frames (upstream's tf_frame_prefix default)
    for ns in ("alpha", "robot_1"):
        odom = out[f"/{ns}/diff_drive_controller/odom"]
        assert (odom.header.frame_id, odom.child_frame_id) == (f"{ns}/odom", f"{ns}/base_link")
