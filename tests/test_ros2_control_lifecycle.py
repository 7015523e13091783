"""Controllers across deactivation and reactivation, as upstream's: an executing action goal
is aborted when its controller is deactivated; goals are known by the face's number."""

from __future__ import annotations

from builtin_interfaces.msg import Duration
from control_msgs.action import FollowJointTrajectory, ParallelGripperCommand
from trajectory_msgs.msg import JointTrajectoryPoint

from nodes.ros2_control.goals import ABORTED, DEACTIVATED, INVALID_GOAL
from nodes.ros2_control.interface import JointReading
from nodes.ros2_control.registry import controller_class
from orchestrator.ros_surface.controller_actions import (
    FollowJointTrajectoryFace,
    ParallelGripperFace,
)

JTC = "joint_trajectory_controller/JointTrajectoryController"
GRIPPER = "parallel_gripper_action_controller/GripperActionController"


def trajectory_goal(name: str, joints: list[str], target: float):
    goal = FollowJointTrajectory.Goal()
    goal.trajectory.header.frame_id = name
    goal.trajectory.joint_names = joints
    goal.trajectory.points = [JointTrajectoryPoint(positions=[target] * len(joints),
                                                   time_from_start=Duration(sec=2))]
    return goal


def gripper_goal(name: str, position: float):
    goal = ParallelGripperCommand.Goal()
    goal.command.header.frame_id = name
    goal.command.position = [position]
    return goal


def active(kind: str, state: dict, **params):
    cls = controller_class(kind)
    ctrl = cls(kind.split("/")[0], cls.Params(**params))
    ctrl.configure()
    ctrl.activate(state)
    return ctrl


def test_a_deactivation_aborts_the_executing_goal_of_either_action_controller():
    state = {"a": JointReading(0.4), "b": JointReading(-0.2)}
    jtc = active(JTC, state, joints=["a", "b"], command_interfaces=["position"])
    assert jtc.on_message("~/cosim/goal", trajectory_goal("cosim-goal-7", ["a", "b"], 1.0),
                          0) == []
    jtc.update(10_000_000, 10_000_000)
    assert jtc.metrics()["goal_state"] == 1.0
    jtc.deactivate()
    m = jtc.metrics()
    assert (m["goal_seq"], m["goal_state"], m["error_code"], m["deactivated"]) == (
        7.0, ABORTED, INVALID_GOAL, 1.0)
    ending = FollowJointTrajectoryFace.ended(m["goal_state"], m, jtc, False)
    assert ending.how == "abort" and ending.text == DEACTIVATED
    assert ending.result.error_code == INVALID_GOAL and ending.result.error_string == DEACTIVATED

    gripper = active(GRIPPER, state, joint="a")
    gripper.on_message("~/cosim/goal", gripper_goal("cosim-goal-12", 0.0), 0)
    assert gripper.update(10_000_000, 10_000_000).commands == {"a/position": 0.0}
    gripper.deactivate()
    m = gripper.metrics()
    assert (m["goal_seq"], m["goal_state"], m["deactivated"]) == (12.0, ABORTED, 1.0)
    ending = ParallelGripperFace.ended(m["goal_state"], m, gripper, False)
    assert ending.how == "abort" and ending.text == DEACTIVATED


def test_a_message_held_from_before_an_activation_is_not_taken_again(tmp_path):
    """The external node republishes the latest message every tick: a group command and a
    trajectory goal held across deactivation, or unload/load/configure, are not acted on."""
    from std_msgs.msg import Float64MultiArray

    from nodes.ros2_control.config import read_controllers_file
    from nodes.ros2_control.manager import ControllerManager
    from tests.test_ros2_control_controllers import controllers_file

    file = read_controllers_file(controllers_file(
        tmp_path, {"arm": "position_controllers/JointGroupPositionController", "jtc": JTC},
        {"arm": {"joints": ["a"]}, "jtc": {"joints": ["b"], "command_interfaces": ["position"]}}))
    manager = ControllerManager(file)
    state = {"a": JointReading(0.3), "b": JointReading(-0.2)}
    manager.activate(["arm", "jtc"], state)
    held = {"/arm/commands": Float64MultiArray(data=[1.0]),
            "/jtc/cosim/goal": trajectory_goal("cosim-goal-1", ["b"], 0.5)}
    assert manager.update(0, 20_000_000, held).commands["a/position"] == 1.0
    assert manager.metrics()["goal_state:jtc"] == 1.0
    manager.switch([], ["arm", "jtc"], state)
    assert manager.metrics()["goal_state:jtc"] == ABORTED
    manager.update(20_000_000, 20_000_000, held)
    for verb in ("unload", "load", "configure"):
        assert manager.lifecycle(verb, "jtc") is None
        manager.update(40_000_000, 20_000_000, held)
    manager.switch(["arm", "jtc"], [], state)
    done = manager.update(60_000_000, 20_000_000, held)
    assert "a/position" not in done.commands  # nothing new sent: nothing commanded
    assert done.commands["b/position"] == -0.2  # holds; the held goal is not executed again
    assert manager.metrics()["goal_state:jtc"] == 0.0  # a fresh controller: no goal


DIFF = "diff_drive_controller/DiffDriveController"
MS = 1_000_000


def test_diff_drive_times_out_from_the_stamp_and_integrates_the_elapsed_time():
    from geometry_msgs.msg import TwistStamped

    from nodes.ros2_control.controllers.diff_drive_controller import Limits, limit

    state = {"l": JointReading(0.0), "r": JointReading(0.0)}
    dd = active(DIFF, state, left_wheel_names=["l"], right_wheel_names=["r"],
                wheel_separation=0.5, wheel_radius=0.1, cmd_vel_timeout=0.5)
    cmd = TwistStamped()
    cmd.twist.linear.x = 1.0
    cmd.header.stamp.sec = 1  # sent at 1 s, taken at 1.4 s: stale from 1.5 s
    dd.on_message("~/cmd_vel", cmd, 1_400 * MS)
    assert dd.update(1_490 * MS, 20 * MS).commands["l/velocity"] > 0.0
    assert dd.update(1_510 * MS, 20 * MS).commands == {"l/velocity": 0.0, "r/velocity": 0.0}
    # odometry over the time since the last update, not the nominal period
    state["l"], state["r"] = JointReading(1.0), JointReading(1.0)  # 0.1 m in 100 ms
    dd.update(1_610 * MS, 20 * MS)
    assert abs(dd.odometry.x - 0.1) < 1e-9 and abs(dd.odometry._window[-1][0] - 1.0) < 1e-9
    dd.deactivate()
    state["l"], state["r"] = JointReading(5.0), JointReading(5.0)  # moved while inactive
    dd.activate(state)
    dd.update(3_000 * MS, 20 * MS)  # starts from the wheels as they are: no jump, no spike
    assert abs(dd.odometry.x - 0.1) < 1e-9 and dd.odometry._window[-1][0] == 1.0
    # min_acceleration bounds the change from below, as upstream's speed limiter
    assert limit(Limits(min_acceleration=-1.0), 0.0, 1.0, 0.1) == 0.9
    assert limit(Limits(), 0.0, 1.0, 0.1) == 0.0


def test_parameters_read_and_not_applied_are_noted():
    dd = controller_class(DIFF)("dd", controller_class(DIFF).Params(
        left_wheel_names=["l"], right_wheel_names=["r"], wheel_separation=0.5,
        wheel_radius=0.1, open_loop=True, enable_odom_tf=False,
        linear={"x": {"max_acceleration_reverse": 1.0, "max_deceleration_reverse": 1.0}}))
    assert dd.notes() == [
        "dd: linear.x.max_acceleration_reverse is not applied (the forward limits apply both "
        "ways).",
        "dd: linear.x.max_deceleration_reverse is not applied (the forward limits apply both "
        "ways).",
        "dd: open_loop is not applied: the odometry integrates the wheels' positions."]
    jsb = "joint_state_broadcaster/JointStateBroadcaster"
    cls = controller_class(jsb)
    assert cls("jsb", cls.Params()).notes() == []
    assert cls("jsb", cls.Params(frame_id="world")).notes() == [
        "jsb: frame_id is not applied: /joint_states carries no frame."]


def test_requests_of_one_tick_merge_and_each_is_handled_once_by_its_id(tmp_path):
    """Two spawners within one tick: both requests enter (merged, one a line); the node
    handles each id once (the external node holds the message), reports the newest and the
    refused ones, and a refused switch names the word it cannot read."""
    from std_msgs.msg import String

    from nodes.ros2_control.config import read_controllers_file
    from nodes.ros2_control.hosted import RobotManager
    from nodes.ros2_control.interface import Fresh
    from nodes.ros2_control.manager import ControllerManager
    from runtime.arrivals import Arrivals
    from tests.test_ros2_control_controllers import controllers_file

    topic = "/controller_manager/cosim/switch"
    arrivals = Arrivals({topic: String})
    merge = lambda waiting, msg: String(data=f"{waiting.data}\n{msg.data}")  # noqa: E731
    assert arrivals.put(topic, String(data="#1 configure:arm"), merge) is None
    assert arrivals.put(topic, String(data="#2 configure:arm"), merge) is None
    assert arrivals.take() == {topic: String(data="#1 configure:arm\n#2 configure:arm")}

    file = read_controllers_file(controllers_file(
        tmp_path, {"arm": "position_controllers/JointGroupPositionController"},
        {"arm": {"joints": ["a"]}}))
    node = RobotManager.__new__(RobotManager)  # its switch logic only
    node.manager, node.fresh, node.request, node.refused = ControllerManager(file), Fresh(), 0, []
    node.system = type("Hardware", (), {"state": {"a": JointReading(0.0)}})()
    notes: list[str] = []
    node.note = notes.append
    held = String(data="#1 configure:arm\n#2 configure:arm\n#3 +arm bogus")
    node._switch(held)
    metrics = node.metrics()
    assert metrics["request"] == 3.0 and "refused:1" not in metrics and "refused:2" not in metrics
    assert metrics["refused:3"] == 1.0 and notes == [
        "switch_controller refused: '+arm bogus': 'bogus' is not '+name' (activate) or "
        "'-name' (deactivate) (request 3)"]
    node._switch(held)  # held by the external node: nothing is done again
    assert node.metrics()["request"] == 3.0 and "refused:3" not in node.metrics()
    node._switch(String(data="#4 +arm"))
    assert node.manager.active() == ["arm"] and len(notes) == 1
    node._switch(String(data="#5 configure:arm"))  # the face planned on an older state
    assert node.metrics()["refused:5"] == 1.0
    assert notes[-1] == ("configure_controller refused: Controller 'arm' can not be configured "
                         "from 'active' state. (request 5)")


def test_an_inactive_controller_the_hardware_cannot_serve_loads_and_its_activation_is_refused(
        tmp_path):
    """As upstream (UR's forward_velocity_controller on position servos): the file loads;
    only activating it is refused, naming what the hardware lacks."""
    import yaml

    from descriptions.load import load_scenario
    from nodes.ros2_control.config import read_controllers_file
    from nodes.ros2_control.hardware import CommandJoint, HardwareInfo, unservable
    from nodes.ros2_control.manager import ControllerManager
    from tests.test_ros2_control_controllers import arm_scenario, controllers_file

    path = arm_scenario(tmp_path, effort_joint="wrist_2")  # 'push': effort on a velocity servo
    doc = yaml.safe_load(path.read_text())
    doc["nodes"][1]["params"]["inactive"] = ["push"]
    path.write_text(yaml.safe_dump(doc))
    load_scenario(path)  # no ScenarioError: push is not active at the start

    file = read_controllers_file(controllers_file(
        tmp_path, {"vel": "velocity_controllers/JointGroupVelocityController"},
        {"vel": {"joints": ["j1"]}}))
    manager = ControllerManager(file)
    info = HardwareInfo(("j1",), (CommandJoint("j1", "position", "j1_servo"),))
    manager.unservable = unservable(manager.controllers, info)
    _, problem = manager.switch(["vel"], [], {"j1": JointReading(0.0)})
    assert problem == ("controller 'vel' cannot be activated: joint 'j1' has no velocity "
                       "command interface in cosim's hardware: its MuJoCo actuator 'j1_servo' "
                       "takes position commands")
    assert manager.active() == []
