"""A robot described in xacro runs as a cosim robot (scenarios/nav_urdf.yaml): it reaches the
nav goal with one digest in-process and multi-process, and a plain rclpy subscriber sees
/robot_description, /joint_states and TF under the URDF's own names, at the root as
robot_state_publisher publishes one robot (tests/test_robot_namespace.py: with a namespace,
and two robots). Bad settings are
scenario errors (exit 2) naming the key."""

from __future__ import annotations

import subprocess
import time

import pytest
import yaml

from descriptions.load import load_scenario
from plan.errors import ScenarioError
from tests.helpers import ORCHESTRATE, ROOT, orchestrate
from tests.sim_client import OK, SimClient

NAV_URDF = ROOT / "scenarios" / "nav_urdf.yaml"
LINKS = {"base_footprint", "base_link", "wheel_left_link", "wheel_right_link",
         "caster_front_link", "caster_back_link", "base_scan", "imu_link", "camera_link",
         "camera_optical_frame"}


def test_nav_urdf_reaches_the_goal_with_one_digest(tmp_path):
    inproc = orchestrate(NAV_URDF, tmp_path, "--in-process", "--quiet")
    multi = orchestrate(NAV_URDF, tmp_path, "--quiet")
    for run in (inproc, multi):
        assert run.code == 0, run.stderr
        assert run.manifest["outcome"]["success"]
        assert run.manifest["outcome"]["metrics"]["mybot/arrived"] == 1.0
    assert inproc.manifest["digest"] == multi.manifest["digest"]


def test_ros_users_see_the_robot_under_its_own_names(tmp_path, ros_node):
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState
    from simulation_interfaces.msg import SimulationState
    from std_msgs.msg import String
    from tf2_msgs.msg import TFMessage

    node, executor = ros_node
    latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                         reliability=ReliabilityPolicy.RELIABLE)
    got: dict[str, list] = {"description": [], "joints": [], "tf": [], "static": []}
    node.create_subscription(String, "/robot_description", got["description"].append,
                             latched)
    node.create_subscription(TFMessage, "/tf_static", got["static"].append, latched)
    node.create_subscription(JointState, "/joint_states", got["joints"].append, 100)
    node.create_subscription(TFMessage, "/tf", got["tf"].append, 100)
    # as a ROS user does: start the run paused, see its topics, then play (a lockstep run
    # does not wait for outside subscribers, and a whole run takes two seconds of wall time,
    # less than discovery may take on a busy machine)
    proc = subprocess.Popen([*ORCHESTRATE, str(NAV_URDF), "--out", str(tmp_path), "--quiet",
                             "--paused"],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    sim = SimClient(ros_node)
    try:
        sim.spin_until(lambda: all(node.get_publishers_info_by_topic(t) for t in (
            "/joint_states", "/tf", "/robot_description", "/tf_static")))
        sim.spin(0.5)  # the run's writers match the subscriptions too
        assert sim.set_state(SimulationState.STATE_PLAYING).result == OK
        deadline = time.monotonic() + 120
        while proc.poll() is None and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        for _ in range(40):
            executor.spin_once(timeout_sec=0.05)
    finally:
        sim.close()
        if proc.poll() is None:
            proc.kill()
        _, err = proc.communicate(timeout=30)
    assert proc.returncode == 0, err
    counts = {k: len(v) for k, v in got.items()}
    assert got["description"], f"no /robot_description; received {counts}"
    urdf = got["description"][-1].data
    assert '<robot name="mybot"' in urdf and "<samples>360</samples>" in urdf  # expanded
    static = {(t.header.frame_id, t.child_frame_id) for m in got["static"] for t in m.transforms}
    assert ("base_link", "base_scan") in static
    assert ("camera_link", "camera_optical_frame") in static
    moving = {(t.header.frame_id, t.child_frame_id) for m in got["tf"] for t in m.transforms}
    assert ("odom", "base_footprint") in moving
    assert ("base_link", "wheel_left_link") in moving
    frames = {c for _, c in static | moving}
    assert LINKS - {"base_footprint"} <= frames
    assert got["joints"] and got["joints"][-1].name == ["wheel_left_joint", "wheel_right_joint"]


def write_scenario(tmp_path, change) -> str:
    doc = yaml.safe_load(NAV_URDF.read_text())
    doc["world"] = str((NAV_URDF.parent / doc["world"]).resolve())
    doc["robots"]["description"] = str(NAV_URDF.parent / doc["robots"]["description"])
    doc["robots"]["urdf"]["packages"] = {
        k: str((NAV_URDF.parent / v).resolve())
        for k, v in doc["robots"]["urdf"]["packages"].items()}
    change(doc)
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(doc))
    return str(path)


def test_a_urdf_robot_without_an_imu_is_named_in_the_physics_params(tmp_path):
    path = write_scenario(tmp_path, lambda d: d["robots"]["urdf"]["args"].update(
        with_imu="false"))
    with pytest.raises(ScenarioError, match="the robot has no IMU") as exc:
        load_scenario(path)
    assert exc.value.key == "nodes[0] (physics).params.imu"


@pytest.mark.parametrize("scenario", ["nav", "swarm"])
def test_robot_description_of_an_mjcf_robot_is_named_in_the_physics_params(scenario):
    """An MJCF robot, alone or in a swarm, has no URDF for /robot_description: the plan
    gives the physics node's world check no described robot model."""
    with pytest.raises(ScenarioError, match="no URDF to publish") as exc:
        load_scenario(ROOT / "scenarios" / f"{scenario}.yaml",
                      {"nodes.physics.params.robot_description": True})
    assert exc.value.key == "nodes[0] (physics).params.robot_description"


@pytest.mark.parametrize("change,key,words", [
    (lambda d: d["robots"]["urdf"].pop("packages"), "robots.description",
     r"\$\(find mybot_description\)"),
    (lambda d: d["robots"]["urdf"].update(wheels=["wheel_left_joint", "imu_joint"]),
     "robots.description", "joint 'imu_joint'.*fixed: it does not turn"),
    (lambda d: d["robots"]["urdf"].update(sensors={"lidar": "laser"}), "robots.description",
     "link 'laser'.*not in the description"),
    (lambda d: d["robots"]["urdf"]["args"].update(wheel_raduis=0.08),
     "robots.urdf.args.wheel_raduis",
     "'wheel_raduis' is not declared.*declares: lidar_samples, with_camera, with_imu"),
    (lambda d: d["robots"].update(description=str(ROOT / "scenarios/worlds/robot.xml")),
     "robots.urdf", "not a URDF or xacro"),
])
def test_bad_urdf_settings_are_scenario_errors(tmp_path, change, key, words):
    path = write_scenario(tmp_path, change)
    with pytest.raises(ScenarioError, match=words) as exc:
        load_scenario(path)
    assert exc.value.key == key
    run = subprocess.run([*ORCHESTRATE, path, "--in-process", "--out", str(tmp_path)],
                         capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert run.returncode == 2 and key in run.stderr


def without_the_lidar_tag(tmp_path) -> str:
    """nav_urdf with mybot copied and its lidar's Gazebo tag taken out: base_scan is a link
    with no sensor on it, as in a description written without Gazebo in mind."""
    import re
    import shutil

    package = tmp_path / "mybot_description"
    shutil.copytree(NAV_URDF.parent / "robots" / "mybot_description", package)
    xacro = package / "urdf" / "mybot.urdf.xacro"
    text, count = re.subn(r'<gazebo reference="base_scan">.*?</gazebo>', "",
                          xacro.read_text(), flags=re.S)
    assert count == 1
    xacro.write_text(text)

    def change(doc):
        doc["robots"]["description"] = str(xacro)
        doc["robots"]["urdf"]["packages"] = {"mybot_description": str(package)}
        doc["robots"]["urdf"]["args"] = {}
    return write_scenario(tmp_path, change)


@pytest.mark.parametrize("mode", ["--in-process", "--pack=node"])
def test_a_lidar_node_for_a_robot_without_a_lidar_is_refused_before_anything_starts(
        tmp_path, mode):
    path = without_the_lidar_tag(tmp_path)
    with pytest.raises(ScenarioError) as exc:
        load_scenario(path)
    problems = {e.key: e for e in exc.value.errors}
    assert set(problems) == {"nodes[1] (lidar@mybot).params.lidar", "nodes[2] (control@mybot)"}
    for error in problems.values():
        assert error.problem.startswith("the robot has no lidar")
        assert "robots.urdf.sensors: {lidar: LINK}" in error.accepted
        assert "Gazebo ray sensor tag" in error.accepted
        assert "site" not in str(error) and "'laser'" not in str(error)  # cosim's MJCF names
    out = tmp_path / "runs"
    run = orchestrate(tmp_path / "bad.yaml", out, mode, "--quiet")
    assert run.code == 2, run.stderr
    assert "the robot has no lidar" in run.stderr and "internal error" not in run.stderr
    assert not out.exists() or not any(out.iterdir())  # nothing started, nothing written
    # the same robot with the lidar named in the scenario runs
    doc = yaml.safe_load((tmp_path / "bad.yaml").read_text())
    doc["robots"]["urdf"]["sensors"] = {"lidar": "base_scan"}
    (tmp_path / "bad.yaml").write_text(yaml.safe_dump(doc))
    assert load_scenario(path).nodes["lidar@mybot"]


@pytest.mark.parametrize("change,key,words", [
    (lambda d: (d["robots"]["urdf"]["args"].update(with_camera="false"), d["nodes"].append(
        {"name": "camera", "kind": "sensors", "for_each": "robot", "rate": 2,
         "params": {"camera": {"width": 32, "height": 24}},
         "inputs": [{"topic": "/cosim/world_state", "mode": "same_tick"}]})),
     "nodes[3] (camera@mybot).params.camera", "the robot has no camera"),
])
def test_a_node_needing_what_the_urdf_robot_lacks_names_the_fix(tmp_path, change, key, words):
    with pytest.raises(ScenarioError) as exc:
        load_scenario(write_scenario(tmp_path, change))
    assert exc.value.key == key and exc.value.problem.startswith(words), exc.value
    assert "Gazebo camera sensor tag" in exc.value.accepted
    assert "robots.urdf.sensors: {camera: LINK}" in exc.value.accepted


def test_arm_targets_not_matching_the_urdf_arms_joints_are_refused(tmp_path):
    doc = yaml.safe_load((ROOT / "scenarios" / "arm_urdf.yaml").read_text())
    doc["world"] = str(ROOT / "scenarios" / "worlds" / "arena.xml")
    doc["robots"]["description"] = str(ROOT / "scenarios" / doc["robots"]["description"])
    doc["robots"]["urdf"]["packages"] = {
        "myarm_description": str(ROOT / "scenarios" / "robots" / "myarm_description")}
    doc["nodes"][1]["params"]["targets"][1] = [0.0, 0.6, 0.8]
    path = tmp_path / "arm.yaml"
    path.write_text(yaml.safe_dump(doc))
    run = orchestrate(path, tmp_path / "runs", "--in-process", "--quiet")
    assert run.code == 2, run.stderr
    assert "nodes[1] (arm@myarm).params.targets[1]: 3 positions for the 6 joints" in run.stderr
    assert "shoulder_pan, shoulder_lift, elbow, wrist_1, wrist_2, wrist_3" in run.stderr


def test_a_xacro_arg_reaches_the_lidar_through_the_gazebo_tag(tmp_path):
    from tests.test_arm import bag_messages

    run = orchestrate(NAV_URDF, tmp_path, "--in-process", "--quiet", "--duration", "1s",
                      "--set", "robots.urdf.args.lidar_samples=180")
    assert run.code == 1, run.stderr  # 1 s: the goal is not reached yet
    scan = bag_messages(run.run_dir, "/scan")[0]
    assert len(scan.ranges) == 180 and scan.header.frame_id == "base_scan"
    assert scan.range_max == pytest.approx(12.0)


def test_a_swarm_of_urdf_robots_reaches_its_goals(tmp_path):
    from tests.test_arm import bag_messages

    run = orchestrate(ROOT / "scenarios" / "swarm_urdf.yaml", tmp_path, "--in-process",
                      "--quiet")
    assert run.code == 0, run.stderr
    assert run.manifest["outcome"]["metrics"]["robots_arrived"] == 4.0
    static = bag_messages(run.run_dir, "/tf_static")[0].transforms
    assert {(t.header.frame_id, t.child_frame_id) for t in static} >= {
        (f"bot_{i}/base_link", f"bot_{i}/base_scan") for i in range(4)}
    assert len(bag_messages(run.run_dir, "/bot_3/robot_description")) == 1


def test_a_urdf_arm_follows_joint_commands_to_its_last_target(tmp_path):
    from tests.test_arm import bag_messages

    run = orchestrate(ROOT / "scenarios" / "arm_urdf.yaml", tmp_path, "--in-process",
                      "--quiet")
    assert run.code == 0, run.stderr
    assert run.manifest["outcome"]["metrics"]["target"] == 2.0  # the third of three
    last = yaml.safe_load((ROOT / "scenarios" / "arm_urdf.yaml").read_text())
    target = last["nodes"][1]["params"]["targets"][-1]
    states = bag_messages(run.run_dir, "/joint_states")[-1]
    assert states.name == ["shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2",
                           "wrist_3"]
    assert list(states.position) == pytest.approx(target, abs=0.05)
    moving = {(t.header.frame_id, t.child_frame_id)
              for t in bag_messages(run.run_dir, "/tf")[-1].transforms}
    assert ("wrist_2_link", "wrist_3_link") in moving
    static = {(t.header.frame_id, t.child_frame_id)
              for t in bag_messages(run.run_dir, "/tf_static")[0].transforms}
    assert ("wrist_3_link", "tool0") in static
