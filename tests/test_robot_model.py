"""The one robot model (descriptions.robot_model), read once from a scenario's world by
descriptions.robot_reader and carried to the nodes in NodeConfig.robots: for the nav robot
(MJCF and USD worlds alike), the arm, and every robot of a swarm under its prefix."""

from __future__ import annotations

from dataclasses import replace

import mujoco
import pytest

from descriptions.load import load_scenario
from descriptions.robot_model import RobotModel
from descriptions.robot_reader import RobotNames, read_robot
from nodes.arm.node import JointTargetsNode
from nodes.physics.node import PhysicsNode
from runtime.build import make_node, node_config, scenario_robots
from tests.helpers import ROOT

SCENARIOS = ROOT / "scenarios"
ARM_JOINTS = ("shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3")


def test_the_nav_robot_as_its_world_describes_it():
    (robot,) = scenario_robots(load_scenario(SCENARIOS / "nav.yaml"))
    assert (robot.name, robot.prefix, robot.base_link, robot.base) == ("", "", "base_link",
                                                                       "base_link")
    assert robot.mobile
    d = robot.drive
    assert (d.left_joint, d.right_joint) == ("left_wheel_joint", "right_wheel_joint")
    assert (d.left_actuator, d.right_actuator) == ("left_wheel_motor", "right_wheel_motor")
    assert (d.wheel_radius, d.wheel_separation) == pytest.approx((0.06, 0.4))
    assert [(a.joint, a.actuator, a.interface) for a in robot.actuated] == [
        ("pan_joint", "pan_servo", "position"), ("tilt_joint", "tilt_servo", "position")]
    assert [(s.kind, s.link, s.mujoco_name) for s in robot.sensors] == [
        ("lidar", "laser", "laser"), ("imu", "imu_link", "imu"),
        ("camera", "camera_color_optical_frame", "rgbd")]
    links = {link.name: (link.body, link.site) for link in robot.links}
    assert links["laser"] == ("base_link", "laser")  # a sensor frame stays a frame
    assert {"base_link", "left_wheel", "pan_link", "tilt_link"} <= set(links)
    joints = {j.name: (j.kind, j.parent, j.child) for j in robot.joints}
    assert joints["tilt_joint"] == ("revolute", "pan_link", "tilt_link")
    assert joints["left_wheel_joint"][0] == "continuous"
    assert robot.footprint_radius == pytest.approx(0.2632, abs=1e-4)


def test_the_usd_world_gives_the_same_robot():
    # every description format produces the same model: nav.usda attaches robot.xml
    (mjcf,) = scenario_robots(load_scenario(SCENARIOS / "nav.yaml"))
    (usd,) = scenario_robots(load_scenario(SCENARIOS / "nav_usd.yaml"))
    assert replace(usd, source="", footprint_radius=0.0) == replace(mjcf, source="",
                                                                    footprint_radius=0.0)
    assert usd.footprint_radius == pytest.approx(mjcf.footprint_radius, abs=1e-9)


def test_the_arm_is_read_by_the_names_its_physics_node_gives():
    s = load_scenario(SCENARIOS / "arm.yaml")
    (arm,) = scenario_robots(s)
    assert not arm.mobile and arm.drive is None
    assert tuple(a.joint for a in arm.actuated) == ARM_JOINTS
    assert tuple(a.actuator for a in arm.actuated) == tuple(f"{j}_servo" for j in ARM_JOINTS)
    assert arm.sensor("lidar") is None and arm.sensor("camera") is None
    # its TF frames on sites, as its physics node's tf parameters name them (no cameras)
    assert [(k.name, k.body, k.site) for k in arm.site_frames] == [
        ("tool0", "wrist_3_link", "tool0")]
    assert arm.camera_frames == ()
    assert node_config(s, "physics").robots == (arm,)
    assert node_config(s, "arm").robots == (arm,)


def test_the_arm_commands_the_robot_models_joints_when_not_told():
    s = load_scenario(SCENARIOS / "arm.yaml", {"nodes.arm.params.joints": None})
    node = make_node(s, "arm")
    assert isinstance(node, JointTargetsNode)
    assert tuple(node.params.joints) == ARM_JOINTS


def test_every_robot_of_a_swarm_is_the_description_scoped_to_it():
    s = load_scenario(SCENARIOS / "swarm.yaml")
    robots = scenario_robots(s)
    assert [r.name for r in robots] == [f"robot_{i}" for i in range(8)]
    alone = read_robot(mujoco.MjModel.from_xml_path(str(s.robots.description)), RobotNames.of(
        PhysicsNode.description_names(s.nodes["physics"].params)))
    for robot in robots:
        assert robot.prefix == f"{robot.name}/"
        assert robot.base_link == f"{robot.name}/base_link"
        assert robot.drive.left_joint == f"{robot.name}/left_wheel_joint"
        assert robot.sensor("lidar").mujoco_name == f"{robot.name}/laser"
        assert dict(robot.sensor("imu").readings) == {  # what physics' IMU reads, by name
            "gyro": f"{robot.name}/imu_gyro", "accelerometer": f"{robot.name}/imu_accel",
            "orientation": f"{robot.name}/imu_quat"}
        n = robot.name
        assert [(k.name, k.site) for k in robot.site_frames] == [(f"{n}/laser", f"{n}/laser")]
        assert [(c.camera, c.link, c.color_optical) for c in robot.camera_frames] == [
            (f"{n}/rgbd", f"{n}/camera_link", f"{n}/camera_color_optical_frame")]
        # read in the swarm world under its prefixed names = the description, scoped
        assert robot == replace(alone.scoped(robot.name), source=robot.source,
                                footprint_radius=robot.footprint_radius)
        assert robot.footprint_radius == pytest.approx(alone.footprint_radius, abs=1e-9)
    # the world node serves every robot; a robot's own nodes serve it alone
    assert node_config(s, "physics").robots == robots
    assert node_config(s, "lidar@robot_3").robots == (robots[3],)
    assert node_config(s, "control@robot_5").robots == (robots[5],)


def test_the_world_node_declares_one_robot_and_serves_each_under_its_namespace():
    s = load_scenario(SCENARIOS / "swarm.yaml")
    physics = s.nodes["physics"]
    assert "robots" not in PhysicsNode.Params.model_fields  # the list reaches it once
    assert physics.spec.robots == [f"robot_{i}" for i in range(8)]
    assert {"/robot_0/odom", "/robot_7/joint_states", "/tf", "/cosim/world_state"} <= set(
        physics.outputs)
    assert "/odom" not in physics.outputs
    assert {i.graph_topic for i in physics.inputs} == {f"/robot_{i}/cmd_vel" for i in range(8)}


def test_a_robot_model_is_plain_data():
    import pickle

    (robot,) = scenario_robots(load_scenario(SCENARIOS / "nav.yaml"))
    assert isinstance(robot, RobotModel)
    assert pickle.loads(pickle.dumps(robot)) == robot
    assert robot.scoped("r").scoped("") == robot.scoped("r")


def test_a_robot_reaches_physics_by_its_model_whatever_described_it():
    # issue 47 item 1: the rig reads an MJCF robot's IMU as a described one's, off the model
    # the plan hands it (names its physics parameters gave the MJCF reader); a URDF robot's
    # IMU sensors are those its reader added; the settings its reader read it with are on it
    from nodes.physics.described_rig import rig_params
    from nodes.physics.imu import ImuParams

    swarm = load_scenario(SCENARIOS / "swarm.yaml")
    params = swarm.nodes["physics"].params.model_copy(update={"imu": ImuParams(
        gyro="g", accelerometer="a", orientation="q")})
    robot = read_robot(mujoco.MjModel.from_xml_path(str(swarm.robots.description)),
                       RobotNames.of(PhysicsNode.description_names(params))).scoped("r")
    imu = rig_params(params, robot).imu
    assert (imu.site, imu.frame_id, imu.gyro, imu.accelerometer, imu.orientation) == (
        "r/imu", "r/imu_link", "r/g", "r/a", "r/q")
    urdf = load_scenario(SCENARIOS / "swarm_urdf.yaml")
    bot = node_config(urdf, "physics").robots[1]
    imu = rig_params(urdf.nodes["physics"].params, bot).imu
    assert (imu.site, imu.gyro, imu.orientation) == ("bot_1/imu_link", "bot_1/imu_link_gyro",
                                                     "bot_1/imu_link_quat")
    assert bot.settings == urdf.robots.settings and bot.reader == "urdf"
