"""ros2_control's controllers behind one interface (nodes/ros2_control/interface.py): each
type a pure object from the registry, with its lifecycle, claims and typed parameters; the
manager loads what a file lists and refuses only the activation of a type cosim cannot run;
the joint group controllers drive position, velocity and effort actuators of a URDF arm's
``<ros2_control>`` block, and a command interface MuJoCo cannot realise is named at load."""

from __future__ import annotations

import pytest
import yaml
from std_msgs.msg import Float64MultiArray

from descriptions.load import load_scenario
from nodes.ros2_control.config import ControllersFileError, read_controllers_file
from nodes.ros2_control.hardware import CommandJoint, HardwareInfo
from nodes.ros2_control.interface import (
    ControllerInterface,
    ControllerParams,
    JointReading,
    LifecycleError,
    LifecycleState,
)
from nodes.ros2_control.manager import ControllerManager
from nodes.ros2_control.registry import CONTROLLER_TYPES, controller_class
from orchestrator.outputs.bag import BagReader
from plan.errors import ScenarioError
from plan.ros_types import message_class
from tests.helpers import ROOT

VELOCITY = "velocity_controllers/JointGroupVelocityController"
EFFORT = "effort_controllers/JointGroupEffortController"
GRIPPER = "position_controllers/GripperActionController"  # a type cosim does not run
ARM_JOINTS = ["shoulder_pan", "shoulder_lift", "elbow", "wrist_1"]


def controllers_file(tmp_path, controllers: dict, params: dict, rate: int = 50):
    doc = {"controller_manager": {"ros__parameters": {"update_rate": rate, **{
        name: {"type": kind} for name, kind in controllers.items()}}},
        **{name: {"ros__parameters": p} for name, p in params.items()}}
    path = tmp_path / "controllers.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def test_every_registered_type_is_a_controller_with_a_parameter_model():
    assert {VELOCITY, EFFORT} <= set(CONTROLLER_TYPES)
    for kind, cls in CONTROLLER_TYPES.items():
        assert issubclass(cls, ControllerInterface), kind
        assert issubclass(cls.Params, ControllerParams), kind
    assert controller_class(GRIPPER) is None


def test_a_group_controller_goes_through_its_lifecycle_and_claims_its_interface():
    ctrl = controller_class(VELOCITY)("v", controller_class(VELOCITY).Params(joints=["a", "b"]))
    assert ctrl.lifecycle is LifecycleState.UNCONFIGURED
    with pytest.raises(LifecycleError):
        ctrl.activate({})
    ctrl.configure()
    assert ctrl.claim().command == ("a/velocity", "b/velocity") and not ctrl.claim().state
    state = {"a": JointReading(0.0), "b": JointReading(1.0)}
    ctrl.activate(state)
    assert ctrl.update(0, 10_000_000).commands == {}  # nothing before the first command
    assert ctrl.on_message("~/commands", Float64MultiArray(data=[1.0]), 0) == [
        "v/commands refused: 1 values for 2 joints ['a', 'b']"]
    assert ctrl.on_message("~/commands", Float64MultiArray(), 0) == []  # nobody sent it
    assert ctrl.on_message("~/commands", Float64MultiArray(data=[0.5, -0.5]), 0) == []
    assert ctrl.update(0, 10_000_000).commands == {"a/velocity": 0.5, "b/velocity": -0.5}
    ctrl.deactivate()
    assert ctrl.lifecycle is LifecycleState.INACTIVE
    ctrl.finalize()
    assert ctrl.lifecycle is LifecycleState.FINALIZED


def test_the_manager_loads_every_listed_type_and_updates_only_active_controllers(tmp_path):
    path = controllers_file(tmp_path, {"jsb": "joint_state_broadcaster/JointStateBroadcaster",
                                       "effort": EFFORT, "gripper": GRIPPER},
                            {"effort": {"joints": ["a"]}, "gripper": {"joint": "a"}})
    file = read_controllers_file(path)
    assert [e.name for e in file.unserved] == ["gripper"]
    manager = ControllerManager(file)
    assert any("gripper: type position_controllers/GripperActionController is loaded" in n
               for n in manager.notes())
    state = {"a": JointReading(0.25, 0.0, 0.0)}
    manager.activate(["jsb"], state)
    inputs = {"/effort/commands": Float64MultiArray(data=[2.0])}
    done = manager.update(0, 20_000_000, inputs)
    assert set(done.published) == {"/joint_states", "/dynamic_joint_states"}
    assert done.commands == {}  # the effort controller is inactive: not updated, no command
    assert {k: v for k, v in manager.metrics().items() if k.startswith("active:")} == {
        "active:jsb": 1.0, "active:effort": 0.0, "active:gripper": 0.0}
    _, problem = manager.switch(["gripper"], [], state)
    assert problem == ("controller 'gripper' has type 'position_controllers/GripperAction"
                       "Controller', which cosim cannot run (it is loaded and stays inactive)")
    _, problem = manager.switch(["effort"], ["jsb"], state)
    assert problem is None and manager.active() == ["effort"]
    done = manager.update(20_000_000, 20_000_000, inputs)
    # the command was sent while it was inactive: dropped, as upstream's, not taken now
    assert done.commands == {} and not done.published
    done = manager.update(40_000_000, 20_000_000,
                          {"/effort/commands": Float64MultiArray(data=[2.0])})
    assert done.commands == {}  # the same message again: nothing new
    done = manager.update(60_000_000, 20_000_000,
                          {"/effort/commands": Float64MultiArray(data=[1.5])})
    assert done.commands == {"a/effort": 1.5}


def test_parameters_are_checked_against_the_types_model(tmp_path):
    dd = "diff_drive_controller/DiffDriveController"
    wheels = {"left_wheel_names": ["l"], "right_wheel_names": ["r"], "wheel_separation": 0.4}
    with pytest.raises(ControllersFileError, match=r"dd\.ros__parameters\.wheel_radius: is "
                       "missing"):
        read_controllers_file(controllers_file(tmp_path, {"dd": dd}, {"dd": wheels}))
    mixed = {**wheels, "wheel_radius": 0.06, "pose_covariance_diagonal": [0, 0, 0, 0, 0, 0.1]}
    with pytest.raises(ControllersFileError, match=r"pose_covariance_diagonal.*write \[0\.0"):
        read_controllers_file(controllers_file(tmp_path, {"dd": dd}, {"dd": mixed}))
    file = read_controllers_file(controllers_file(tmp_path, {"dd": dd}, {"dd": {
        **wheels, "wheel_radius": 0.06, "linear": {"x": {"max_velocity": 0.8}}}}))
    params = file.named("dd").params
    assert params.linear.x.max_velocity == 0.8 and params.cmd_vel_timeout == 0.5


@pytest.mark.parametrize("namespace, prefix, expected", [
    ("", {}, "odom"),  # a lone robot at the root
    ("robot_2", {}, "robot_2/odom"),  # upstream's default: the controller's namespace
    ("robot_2", {"tf_frame_prefix": "fleet/a"}, "fleet/a/odom"),
    ("robot_2", {"tf_frame_prefix": "/fleet/"}, "fleet/odom"),  # tf2 takes no leading '/'
    ("robot_2", {"tf_frame_prefix_enable": False, "tf_frame_prefix": "x"}, "odom"),
])
def test_a_diff_drives_odometry_frames_carry_its_tf_prefix(tmp_path, namespace, prefix,
                                                           expected):
    dd = "diff_drive_controller/DiffDriveController"
    path = controllers_file(tmp_path, {"dd": dd}, {"dd": {
        "left_wheel_names": ["l"], "right_wheel_names": ["r"], "wheel_separation": 0.4,
        "wheel_radius": 0.06, "base_frame_id": "base_footprint", **prefix}})
    manager = ControllerManager(read_controllers_file(path), namespace)
    state = {"l": JointReading(0.0), "r": JointReading(0.0)}
    manager.activate(["dd"], state)
    odom = manager.update(0, 20_000_000, {}).published["/dd/odom"]
    base = expected.removesuffix("odom") + "base_footprint"
    assert (odom.header.frame_id, odom.child_frame_id) == (expected, base)
    manager.switch([], ["dd"], state)
    assert manager.lifecycle("unload", "dd") is None
    assert manager.lifecycle("load", "dd") is None  # loaded again: in the same namespace
    assert manager.controllers["dd"].namespace == namespace


def test_a_command_interface_the_hardware_lacks_is_named_with_its_joint():
    info = HardwareInfo(("j1", "j2"), (CommandJoint("j1", "position", "j1_servo"),))
    claim = controller_class(EFFORT)("e", controller_class(EFFORT).Params(joints=["j1"])).claim()
    (problem, accepted), = info.problems(claim)
    assert problem == ("joint 'j1' has no effort command interface in cosim's hardware: its "
                       "MuJoCo actuator 'j1_servo' takes position commands.")
    assert "j1/position" in accepted
    claim = controller_class(EFFORT)("e", controller_class(EFFORT).Params(joints=["j9"])).claim()
    assert info.problems(claim)[0][0] == "joint 'j9' is not in the world."


# -- a URDF arm's position, velocity and effort joints, driven by three group controllers ----

def arm_scenario(tmp_path, effort_joint: str = "wrist_3"):
    """myarm (its <ros2_control> block: four position joints, wrist_2 velocity, wrist_3
    effort) with a position, a velocity and an effort group controller, fed by clients."""
    controllers_file(tmp_path, {"arm": "position_controllers/JointGroupPositionController",
                                "spin": VELOCITY, "push": EFFORT},
                     {"arm": {"joints": ARM_JOINTS}, "spin": {"joints": ["wrist_2"]},
                      "push": {"joints": [effort_joint]}})
    robots = ROOT / "scenarios" / "robots" / "myarm_description"
    doc = {"name": "arm_groups", "seed": 3, "duration": "600ms", "interactive": True,
           "world": str(ROOT / "scenarios" / "worlds" / "arena.xml"),
           "robots": {"description": str(robots / "urdf" / "myarm.urdf.xacro"),
                      "urdf": {"packages": {"myarm_description": str(robots)}, "base": "fixed",
                               "gains": {"wrist_2": {"kv": 0.5}}},
                      "named": [{"name": "myarm", "start": {"x": 0.0, "y": 0.0},
                                 "goal": {"x": 0.0, "y": 0.0}}]},
           "success": {"reach_goal": False, "max_collisions": 0},
           "nodes": [{"name": "physics", "kind": "physics", "rate": 50,
                      "params": {"robot_description": True, "imu": None}},
                     {"name": "controller_manager", "kind": "ros2_control",
                      "for_each": "robot", "rate": 50,
                      "params": {"controllers": "controllers.yaml"}}]}
    path = tmp_path / "arm_groups.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def test_group_controllers_drive_position_velocity_and_effort_joints(tmp_path):
    from orchestrator.api import run

    commands = {"/arm/commands": Float64MultiArray(data=[0.3, -0.2, 0.4, 0.1]),
                "/spin/commands": Float64MultiArray(data=[1.0]),
                "/push/commands": Float64MultiArray(data=[0.5])}
    done = run(arm_scenario(tmp_path), in_process=True, out=tmp_path / "runs",
               external=lambda k: commands if k >= 1 else {}, picture=False)
    with BagReader(done.run_dir / "bag") as bag:
        states = [m for _, m in bag.messages("/joint_states",
                                             message_class("sensor_msgs/msg/JointState"))]
        # the commands reach the actuators in the physics step: no topic carries them
        assert "/joint_commands" not in bag.counts
    # before any command: positions held, no motion (test_the_hardware_holds_... tells held
    # from zero, which this arm, starting at zero, cannot)
    assert max(abs(p) for p in states[1].position) < 1e-6
    end = dict(zip(states[-1].name, zip(states[-1].position, states[-1].velocity,
                                         strict=True), strict=True))
    for joint, target in zip(ARM_JOINTS, [0.3, -0.2, 0.4, 0.1], strict=True):
        assert abs(end[joint][0] - target) < 0.02, (joint, end[joint])
    # the velocity servo (kv 0.5) against the joint's damping (0.5): half the command, steady
    assert 0.45 < end["wrist_2"][1] < 0.55 and end["wrist_2"][0] > 0.2
    mid = dict(zip(states[len(states) // 2].name, states[len(states) // 2].position,
                   strict=True))
    assert end["wrist_3"][0] > mid["wrist_3"] > 0.1  # a steady torque keeps it turning


def test_the_hardware_holds_positions_where_the_arm_starts_until_a_command():
    """The MuJoCo system reads the joints from MjData and writes commands straight to the
    actuators: before the first update each position servo holds where its joint is."""
    import mujoco

    from nodes.ros2_control.hosted import MujocoSystem

    joints = "".join(f'<body><joint name="{j}"/><geom size=".1" mass="1"/></body>'
                     for j in ("j1", "j2", "j3"))
    model = mujoco.MjModel.from_xml_string(
        f"<mujoco><worldbody>{joints}</worldbody><actuator>"
        '<position name="s1" joint="j1" kp="10"/><velocity name="s2" joint="j2" kv="1"/>'
        '<position name="s3" joint="j3" kp="10"/></actuator></mujoco>')
    data = mujoco.MjData(model)
    data.qpos[:] = [0.3, -0.2, 0.7]
    info = HardwareInfo(("j1", "j2", "j3"), (CommandJoint("j1", "position", "s1"),
                                             CommandJoint("j2", "velocity", "s2"),
                                             CommandJoint("j3", "position", "s3")))
    system = MujocoSystem(model, info, ["j1", "j2", "j3"], [0, 1, 2], [0, 1, 2], None)
    system.read(data)
    assert [system.state[j].position for j in ("j1", "j2", "j3")] == [0.3, -0.2, 0.7]
    system.start(data)
    assert list(data.ctrl) == [0.3, 0.0, 0.7]
    system.write(data, {"j3/position": 0.1, "j9/position": 5.0})  # j9: no such interface
    assert list(data.ctrl) == [0.3, 0.0, 0.1]


def test_an_interface_mujoco_cannot_realise_is_refused_naming_the_joint(tmp_path):
    with pytest.raises(ScenarioError) as err:
        load_scenario(arm_scenario(tmp_path, effort_joint="wrist_2"))
    assert ("push: joint 'wrist_2' has no effort command interface in cosim's hardware: its "
            "MuJoCo actuator 'myarm/wrist_2_velocity' takes velocity commands") in str(err.value)


# -- a parallel gripper, as MoveIt's grasping drives it ----------------------------------------

GRIPPER_ACTION = "parallel_gripper_action_controller/GripperActionController"


def gripper_goal(name: str, *positions: float):
    from control_msgs.action import ParallelGripperCommand

    goal = ParallelGripperCommand.Goal()
    goal.command.header.frame_id = name
    goal.command.position = list(positions)
    return goal


def test_a_parallel_gripper_reaches_stalls_and_holds_on_cancel():
    cls = controller_class(GRIPPER_ACTION)
    ctrl = cls("gripper", cls.Params(joint="finger", stall_timeout=0.1))
    ctrl.configure()
    state = {"finger": JointReading(0.02, 0.0)}
    ctrl.activate(state)
    assert ctrl.claim().command == ("finger/position",)
    assert ctrl.update(0, 10_000_000).commands == {"finger/position": 0.02}  # holds
    assert ctrl.on_message("~/cosim/goal", gripper_goal("cosim-goal-1", 0.04, 0.04), 0) == [
        "gripper/gripper_cmd goal 1 refused: 2 positions, expects 1"]
    ctrl.on_message("~/cosim/goal", gripper_goal("cosim-goal-2", 0.04), 0)
    state["finger"] = JointReading(0.025, 0.05)  # moving towards it
    assert ctrl.update(50_000_000, 10_000_000).commands == {"finger/position": 0.04}
    assert ctrl.metrics()["goal_state"] == 1.0
    state["finger"] = JointReading(0.028, 0.0)  # an object between the fingers: it stops
    ctrl.update(100_000_000, 10_000_000)
    assert ctrl.metrics()["goal_state"] == 1.0  # not yet stall_timeout without motion
    ctrl.update(160_000_000, 10_000_000)
    assert ctrl.metrics() == {"goal_seq": 2.0, "goal_state": 3.0, "error_code": 0.0,
                              "deactivated": 0.0, "stalled": 1.0, "reached_goal": 0.0,
                              "position": 0.028}
    ctrl.on_message("~/cosim/goal", gripper_goal("cosim-goal-3", 0.0281), 200_000_000)
    ctrl.update(210_000_000, 10_000_000)  # within goal_tolerance (0.01)
    assert ctrl.metrics()["goal_state"] == 2.0 and ctrl.metrics()["reached_goal"] == 1.0
    ctrl.on_message("~/cosim/goal", gripper_goal("cosim-goal-4", 0.0), 300_000_000)
    state["finger"] = JointReading(0.02, -0.05)
    ctrl.on_message("~/cosim/goal", gripper_goal("cosim-cancel-5"), 310_000_000)
    assert ctrl.metrics()["goal_state"] == 4.0
    assert ctrl.update(320_000_000, 10_000_000).commands == {"finger/position": 0.02}


def test_a_moveit_users_gripper_goal_is_answered_by_the_gripper_controller(tmp_path, ros_node):
    """A plain rclpy ParallelGripperCommand client against a running arm whose wrist_1 is the
    gripper: the goal succeeds with the joint's state; a goal of two positions is rejected."""
    from control_msgs.action import ParallelGripperCommand
    from simulation_interfaces.msg import SimulationState

    from tests.sim_client import SimClient, orchestrate

    path = arm_scenario(tmp_path)
    controllers_file(tmp_path, {"arm": "position_controllers/JointGroupPositionController",
                                "gripper": GRIPPER_ACTION},
                     {"arm": {"joints": ARM_JOINTS[:3]},
                      "gripper": {"joint": "wrist_1", "goal_tolerance": 0.02}})
    sim = SimClient(ros_node)
    with orchestrate(path, tmp_path / "out", "--paused", "--duration", "2s") as proc:
        sim.send_goal(ParallelGripperCommand, "/gripper/gripper_cmd",
                      gripper_goal("", 0.3, 0.3), accepted=False)
        grasp = sim.send_goal(ParallelGripperCommand, "/gripper/gripper_cmd",
                              gripper_goal("", 0.3))
        sim.set_state(SimulationState.STATE_PLAYING)
        sim.spin_until(lambda: grasp.result.done(), timeout=120)
        outcome = grasp.result.result()
        proc.communicate(timeout=60)
    sim.close()
    assert outcome.status == 4, outcome  # SUCCEEDED
    assert outcome.result.reached_goal and not outcome.result.stalled
    assert outcome.result.state.name == ["wrist_1"]
    assert abs(outcome.result.state.position[0] - 0.3) < 0.02
