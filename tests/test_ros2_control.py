"""ros2_control's standard controllers in lockstep (nodes/ros2_control): the trajectory
sampled as upstream samples it, the controllers file checked at load, and a plain rclpy
client driving the arm as a MoveIt user does (FollowJointTrajectory: success, a path that
cannot be followed, an unknown joint, a cancel), listing and switching controllers, with
one digest across repeats and in-process."""

from __future__ import annotations

import math
import subprocess

import pytest
import yaml
from builtin_interfaces.msg import Duration
from control_msgs.action import FollowJointTrajectory
from control_msgs.msg import JointTolerance
from controller_manager_msgs.srv import ListControllers, SwitchController
from simulation_interfaces.msg import SimulationState
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from descriptions.load import load_scenario
from nodes.ros2_control.config import ControllersFileError, read_controllers_file
from nodes.ros2_control.controllers.diff_drive_controller import DiffDriveOdometry
from nodes.ros2_control.trajectory import Point, Trajectory, interpolate
from orchestrator.lockstep.inprocess import run_in_process
from orchestrator.outputs.bag import BagReader
from plan.errors import ScenarioError
from plan.ros_types import message_class
from tests.helpers import ORCHESTRATE, ROOT
from tests.sim_client import OK, SimClient, live_runs, orchestrate

ARM = ROOT / "scenarios" / "arm_control.yaml"
JOINTS = ["shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3"]
TICK_NS = 10_000_000
SUCCEEDED, CANCELED, ABORTED = 4, 5, 6  # action_msgs/GoalStatus
JTC = "/joint_trajectory_controller/follow_joint_trajectory"
TARGET = [0.5, -0.3, 0.8, 0.2, -0.4, 0.6]


# -- the trajectory, as ros2_controllers samples it -------------------------------------------

def test_positions_only_are_linear_and_the_last_point_is_held():
    before = Point(0, [0.0], [0.0], [0.0])
    traj = Trajectory([Point(1_000_000_000, [1.0]), Point(3_000_000_000, [3.0])], 0, before, 0)
    half = traj.sample(500_000_000)
    assert half.positions == [0.5] and half.velocities == [1.0] and not half.past_end
    assert traj.sample(2_000_000_000).positions == [2.0]
    end = traj.sample(5_000_000_000)
    assert end.positions == [3.0] and end.velocities == [0.0] and end.past_end
    held = traj.sample(4_000_000_000, interpolate_splines=False)
    assert held.positions == [3.0]


def test_velocities_make_a_cubic_and_accelerations_a_quintic():
    a, b = Point(0, [0.0], [0.0]), Point(2_000_000_000, [1.0], [0.0])
    mid = interpolate(0, a, 2_000_000_000, b, 1_000_000_000)
    assert mid.positions[0] == pytest.approx(0.5) and mid.velocities[0] == pytest.approx(0.75)
    quarter = interpolate(0, a, 2_000_000_000, b, 500_000_000)  # 3s^2 - 2s^3 at s = 1/4
    assert quarter.positions[0] == pytest.approx(3 / 16 - 2 / 64)
    a5, b5 = Point(0, [0.0], [0.0], [0.0]), Point(1_000_000_000, [1.0], [0.0], [0.0])
    q = interpolate(0, a5, 1_000_000_000, b5, 250_000_000)  # 10s^3 - 15s^4 + 6s^5
    s = 0.25
    assert q.positions[0] == pytest.approx(10 * s**3 - 15 * s**4 + 6 * s**5)
    assert interpolate(0, a5, 1_000_000_000, b5, 1_000_000_000).positions[0] == pytest.approx(1)


def test_wheel_odometry_integrates_a_straight_line_and_an_arc():
    odo = DiffDriveOdometry(separation=0.5, left_radius=0.1, right_radius=0.1)
    odo.update(0.0, 0.0, 0.01)
    for k in range(1, 101):
        odo.update(k * 0.1, k * 0.1, 0.01)  # 1 cm per update on each side
    assert (odo.x, odo.y, odo.heading) == (pytest.approx(1.0), pytest.approx(0.0), 0.0)
    assert odo.linear == pytest.approx(1.0)
    turn = DiffDriveOdometry(separation=0.5, left_radius=0.1, right_radius=0.1)
    turn.update(0.0, 0.0, 0.01)
    quarter = math.pi / 2 * 0.25 / 0.1  # the right wheel's angle for a quarter turn on the spot
    turn.update(-quarter, quarter, 0.01)
    assert turn.heading == pytest.approx(math.pi / 2) and abs(turn.x) < 1e-12


# -- the controllers file, checked at load ------------------------------------------------------

def write(tmp_path, doc: dict, scenario_update: dict | None = None):
    (tmp_path / "controllers.yaml").write_text(yaml.safe_dump(doc))
    scenario = yaml.safe_load(ARM.read_text())
    scenario["world"] = str((ARM.parent / scenario["world"]).resolve())
    cm = next(n for n in scenario["nodes"] if n["name"] == "controller_manager")
    cm["params"]["controllers"] = "controllers.yaml"
    cm["params"]["inactive"] = []
    scenario["nodes"] = [n for n in scenario["nodes"] if n["name"] != "arm"]
    cm["inputs"] = []
    cm.pop("remap")
    scenario.update(scenario_update or {})
    path = tmp_path / "arm_control.yaml"
    path.write_text(yaml.safe_dump(scenario))
    return path


def manager(rate: int = 100, **controllers) -> dict:
    doc = {"controller_manager": {"ros__parameters": {"update_rate": rate}}}
    for name, (kind, params) in controllers.items():
        doc["controller_manager"]["ros__parameters"][name] = {"type": kind}
        if params is not None:
            doc[name] = {"ros__parameters": params}
    return doc


def test_a_type_cosim_cannot_run_loads_and_only_its_activation_is_refused(tmp_path):
    gripper = ("position_controllers/GripperActionController", {"joint": "wrist_3"})
    jtc = ("joint_trajectory_controller/JointTrajectoryController",
           {"joints": JOINTS, "command_interfaces": ["position"]})
    path = write(tmp_path, manager(jtc=jtc, gripper=gripper))
    with pytest.raises(ScenarioError) as err:  # activated at the start: exit 2, named
        load_scenario(path)
    text = str(err.value)
    assert "'gripper'" in text and "position_controllers/GripperActionController" in text
    assert "joint_trajectory_controller/JointTrajectoryController" in text  # what is served
    bad = subprocess.run([*ORCHESTRATE, str(path), "--quiet"], capture_output=True, text=True,
                         cwd=tmp_path, timeout=120)
    assert bad.returncode == 2 and "GripperActionController" in bad.stderr
    assert not (tmp_path / "runs").exists()
    # listed as inactive, it loads: said at load time, and its activation is refused
    scenario = load_scenario(path, {"nodes.controller_manager.params.inactive": ["gripper"]})
    assert any("'gripper' of type 'position_controllers/GripperActionController' is loaded"
               in str(w) for w in scenario.warnings), scenario.warnings


def test_a_rate_other_than_update_rate_and_unknown_joints_are_refused(tmp_path):
    jtc = ("joint_trajectory_controller/JointTrajectoryController",
           {"joints": JOINTS, "command_interfaces": ["position"]})
    with pytest.raises(ScenarioError, match="update_rate: 50"):
        load_scenario(write(tmp_path, manager(50, jtc=jtc)))
    wrong = ("joint_trajectory_controller/JointTrajectoryController",
             {"joints": [*JOINTS[:5], "wrist_9"], "command_interfaces": ["position"]})
    with pytest.raises(ScenarioError, match="'wrist_9' is not in the world"):
        load_scenario(write(tmp_path, manager(jtc=wrong)))
    velocity = ("velocity_controllers/JointGroupVelocityController", {"joints": JOINTS})
    with pytest.raises(ScenarioError, match="no velocity command interface"):
        load_scenario(write(tmp_path, manager(v=velocity)))


def test_a_controllers_file_reads_namespaced_and_wildcard_blocks(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text(yaml.safe_dump({
        "/**/controller_manager": {"ros__parameters": {"update_rate": 50, "jtc": {
            "type": "joint_trajectory_controller/JointTrajectoryController"}}},
        "/**": {"ros__parameters": {"command_interfaces": ["position"]}},
        "/robot_0/jtc": {"ros__parameters": {"joints": ["a", "b"]}}}))
    spec = read_controllers_file(path)
    assert spec.update_rate == 50 and spec.named("jtc").params.joints == ["a", "b"]
    assert spec.named("jtc").params.command_interfaces == ["position"]  # from /**
    path.write_text("controller_manager: {ros__parameters: {update_rate: 100}}\n")
    with pytest.raises(ControllersFileError, match="names no controller"):
        read_controllers_file(path)


# -- a MoveIt user's client, against the running arm --------------------------------------------

@pytest.fixture(scope="module")
def trajectory_scenario(tmp_path_factory):
    """arm_control with the trajectory controller active (no joint_targets node, the
    forward controller inactive), interactive, no stop at the goal."""
    doc = yaml.safe_load(ARM.read_text())
    doc["world"] = str((ARM.parent / doc["world"]).resolve())
    doc["duration"] = "30s"
    doc["success"]["stop_on_goal"] = False
    doc["nodes"] = [n for n in doc["nodes"] if n["name"] != "arm"]
    cm = next(n for n in doc["nodes"] if n["name"] == "controller_manager")
    cm["params"]["controllers"] = str((ARM.parent / cm["params"]["controllers"]).resolve())
    cm["params"]["inactive"] = ["forward_position_controller"]
    cm["inputs"] = []
    cm.pop("remap")
    path = tmp_path_factory.mktemp("arm") / "arm_trajectory.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def test_only_a_trajectory_a_client_sent_is_noted_as_refused(trajectory_scenario):
    # until a client sends one, the external node publishes an empty trajectory: nobody sent
    # it, so nothing was refused (every run with the trajectory controller active said so)
    scenario = load_scenario(trajectory_scenario, {"duration": "300ms"})
    partial = JointTrajectory(joint_names=JOINTS[:3], points=[
        JointTrajectoryPoint(positions=[0.1] * 3, time_from_start=Duration(sec=1))])
    topic = "/joint_trajectory_controller/joint_trajectory"
    result = run_in_process(scenario, external=lambda k: {topic: partial} if k == 10 else {})
    notes = [(n.node, n.tick, n.text) for n in result.notes]
    assert notes == [("physics", 10, "joint_trajectory_controller/joint_trajectory "
                      "refused: joints ['wrist_1', 'wrist_2', 'wrist_3'] are missing and "
                      "allow_partial_joints_goal is false")]


def goal(points: list[tuple[float, list[float]]], joints=JOINTS, path_tolerance=None
         ) -> FollowJointTrajectory.Goal:
    msg = FollowJointTrajectory.Goal()
    msg.trajectory.joint_names = list(joints)
    for t, positions in points:
        sec, frac = divmod(t, 1)
        msg.trajectory.points.append(JointTrajectoryPoint(
            positions=positions, time_from_start=Duration(sec=int(sec),
                                                          nanosec=round(frac * 1e9))))
    if path_tolerance is not None:
        msg.path_tolerance = [JointTolerance(name=j, position=path_tolerance) for j in joints]
    return msg


def session(sim: SimClient, checks: bool) -> tuple[int, list[float]]:
    """The client's session, all while paused; returns the tick the run was stopped before
    and where the arm was when its goal was cancelled."""
    assert sim.step(5).result == OK
    listed = sim.call(ListControllers, "/controller_manager/list_controllers",
                      ListControllers.Request()).controller
    if checks:
        assert {(c.name, c.type, c.state) for c in listed} == {
            ("joint_state_broadcaster", "joint_state_broadcaster/JointStateBroadcaster",
             "active"),
            ("joint_trajectory_controller",
             "joint_trajectory_controller/JointTrajectoryController", "active"),
            ("forward_position_controller",
             "forward_command_controller/ForwardCommandController", "inactive")}
    unknown = sim.send_goal(FollowJointTrajectory, JTC, goal(
        [(1.0, [0.0] * 6)], joints=[*JOINTS[:5], "gripper"]))
    assert sim.step(5).result == OK
    first = sim.result(unknown)
    # a plan a MoveIt user would send: two points, 1.5 s
    reached = sim.send_goal(FollowJointTrajectory, JTC, goal(
        [(0.75, [v / 2 for v in TARGET]), (1.5, TARGET)]))
    assert sim.step(250).result == OK
    success = sim.result(reached)
    # an arm cannot jump 2 rad in 50 ms: the path tolerance breaks and the arm holds
    jump = sim.send_goal(FollowJointTrajectory, JTC, goal(
        [(0.05, [2.0, 0.0, 0.0, 0.0, 0.0, 0.0])], path_tolerance=0.05))
    assert sim.step(30).result == OK
    violated = sim.result(jump)
    # a long motion, cancelled mid-way: the arm holds where it was
    slow = sim.send_goal(FollowJointTrajectory, JTC, goal([(4.0, [-0.8] * 6)]))
    assert sim.step(100).result == OK
    sim.cancel(slow)
    assert sim.step(2).result == OK
    cancelled = sim.result(slow)
    off = sim.call(SwitchController, "/controller_manager/switch_controller",
                   SwitchController.Request(deactivate_controllers=[
                       "joint_trajectory_controller"]))
    assert sim.step(1).result == OK  # the switch enters at this tick
    after = sim.call(ListControllers, "/controller_manager/list_controllers",
                     ListControllers.Request()).controller
    # a goal for a controller that is not running is rejected, as upstream's is (it was
    # accepted and never answered)
    sim.send_goal(FollowJointTrajectory, JTC, goal([(1.0, [0.0] * 6)]), accepted=False)
    assert sim.step(50).result == OK
    stop = sim.set_state(SimulationState.STATE_STOPPED)
    if checks:
        assert first.status == ABORTED
        assert first.result.error_code == FollowJointTrajectory.Result.INVALID_JOINTS
        assert success.status == SUCCEEDED, success.result.error_string
        assert success.result.error_code == FollowJointTrajectory.Result.SUCCESSFUL
        sim.spin_until(lambda: len(reached.feedback) > 10)
        assert reached.feedback[-1].joint_names == JOINTS
        assert len(reached.feedback[-1].actual.positions) == 6
        assert violated.status == ABORTED, violated.result.error_string
        assert violated.result.error_code == \
            FollowJointTrajectory.Result.PATH_TOLERANCE_VIOLATED
        assert "shoulder_pan" in violated.result.error_string
        assert cancelled.status == CANCELED, cancelled.result.error_string
        assert off.ok, off.message
        states = {c.name: c.state for c in after}
        assert states["joint_trajectory_controller"] == "inactive"
    return int(stop.error_message.split("before tick ")[1].split()[0])


def test_a_moveit_users_client_drives_the_arm_reproducibly(tmp_path, ros_node,
                                                            trajectory_scenario):
    runs = live_runs(ros_node, trajectory_scenario, tmp_path, session)
    assert runs[0].digest == runs[1].digest  # the same requests at the same ticks: one run

    run_dir, digest, stopped_at = runs[0].run_dir, runs[0].digest, runs[0].stopped_at
    with BagReader(run_dir / "bag") as bag:
        states = {s // TICK_NS: m for s, m in bag.messages(
            "/joint_states", message_class("sensor_msgs/msg/JointState"))}
        entered: dict[str, int] = {}  # goal or cancel name -> the tick it entered
        for s, m in bag.messages("/joint_trajectory_controller/cosim/goal",
                                 message_class("control_msgs/action/FollowJointTrajectory_Goal")):
            entered.setdefault(m.trajectory.header.frame_id, s // TICK_NS)
        goals = sorted(k for n, k in entered.items() if n.startswith("cosim-goal-"))
        cancels = sorted(k for n, k in entered.items() if n.startswith("cosim-cancel-"))
        switches = sorted(s // TICK_NS for s, m in bag.messages(
            "/controller_manager/cosim/switch", message_class("std_msgs/msg/String"))
            if m.data.endswith(" -joint_trajectory_controller"))  # '#<id> -name'
    # the successful goal: every joint within its goal tolerance (0.05 rad) at the end
    reached_at = goals[1] + 160
    at = dict(zip(states[reached_at].name, states[reached_at].position, strict=True))
    assert all(abs(at[j] - t) <= 0.05 for j, t in zip(JOINTS, TARGET, strict=True)), at
    # cancelled mid-motion: the arm holds where it was when the cancel entered
    cancel = cancels[0]
    held = [dict(zip(states[k].name, states[k].position, strict=True)) for k in
            (cancel, switches[0] - 1)]
    assert all(abs(held[0][j] - held[1][j]) < 0.02 for j in JOINTS), held
    assert any(abs(held[0][j] - (-0.8)) > 0.2 for j in JOINTS)  # it had not got there

    # in-process, fed what the bag recorded: the same digest
    scenario = load_scenario(trajectory_scenario,
                             {"duration": f"{(stopped_at - 1) * 10}ms"})
    inputs = recorded_inputs(run_dir, scenario)
    assert run_in_process(scenario, external=lambda k: inputs.get(k, {})).digest == digest


def test_a_goal_open_when_the_run_ends_gets_its_result(tmp_path, ros_node,
                                                      trajectory_scenario):
    """A MoveIt user's goal still executing when the run ends (here at its duration) is
    answered, ABORTED with the reason, before the run's servers go: the client waited past
    the run for a result that never came."""
    sim = SimClient(ros_node)
    with orchestrate(trajectory_scenario, tmp_path / "out", "--paused", "--duration",
                     "500ms") as proc:
        slow = sim.send_goal(FollowJointTrajectory, JTC, goal([(4.0, [-0.8] * 6)]))
        assert sim.set_state(SimulationState.STATE_PLAYING).result == OK
        sim.spin_until(lambda: slow.result.done(), timeout=120)
        assert slow.result.done(), "no result for the goal open when the run ended"
        outcome = slow.result.result()
        _, err = proc.communicate(timeout=60)
    sim.close()
    assert outcome.status == ABORTED
    assert "the run ended" in outcome.result.error_string, outcome.result.error_string
    assert "never retrieved" not in err and "Traceback" not in err, err[-3000:]


def recorded_inputs(run_dir, scenario) -> dict[int, dict]:
    """What the external node published at each tick, from the bag, where a client sent
    something (a goal, a cancel, a switch)."""
    topics = scenario.nodes["external"].outputs
    inputs: dict[int, dict] = {}
    last: dict[str, bytes] = {}
    with BagReader(run_dir / "bag") as bag:
        for topic in topics:
            cls = message_class(bag.msgtype(topic))
            for stamp, msg in bag.messages(topic, cls):
                inputs.setdefault(stamp // TICK_NS, {})[topic] = msg
    del last
    return inputs


# -- a Nav2 user's diff drive controller -------------------------------------------------------

@pytest.mark.parametrize(("scenario", "limit"), [
    ("nav_control.yaml", 0.8),  # cosim's MJCF robot
    # a URDF robot in xacro, the robot's own node; alone, so at the root
    ("nav_urdf_control.yaml", 0.8),
])
def test_the_nav_controller_reaches_the_goal_through_a_diff_drive_controller(
        tmp_path, scenario, limit):
    """The built-in controller's TwistStamped goes to the diff drive controller's ~/cmd_vel;
    the controller drives the base's wheels in the physics step; its wheel odometry follows
    the ground truth; one digest in-process and multi-process."""
    from orchestrator.api import run

    done = run(ROOT / "scenarios" / scenario, in_process=True, out=tmp_path / "a", picture=False)
    assert done.success
    with BagReader(done.run_dir / "bag") as bag:
        odom = message_class("nav_msgs/msg/Odometry")
        truth = dict(bag.messages("/odom", odom))
        wheels = dict(bag.messages("/diff_drive_controller/odom", odom))
        assert bag.counts["/diff_drive_controller/cmd_vel"] > 0
        assert not [t for t in bag.counts if t.startswith("/cosim/") and "hardware" in t]
    assert len(wheels) == len(truth)  # the controller is updated at every physics step
    # the base never outruns the controller's linear.x.max_velocity (its one limiter)
    assert max(abs(m.twist.twist.linear.x) for m in truth.values()) <= limit + 0.02
    end = max(wheels)
    (tx, ty), (wx, wy) = ((m.pose.pose.position.x, m.pose.pose.position.y)
                          for m in (truth[end], wheels[end]))
    # the wheel odometry starts at its own origin: compare the travel from the start
    (sx, sy) = (truth[min(truth)].pose.pose.position.x, truth[min(truth)].pose.pose.position.y)
    assert math.hypot(tx - sx, ty - sy) > 8.0
    assert wheels[end].header.frame_id == "odom"
    travelled = math.hypot(wx, wy)
    assert abs(travelled - math.hypot(tx - sx, ty - sy)) < 0.3, (travelled, tx, ty)
    short = run(ROOT / "scenarios" / scenario, in_process=True, out=tmp_path / "b",
                duration="4s", picture=False)
    multi = run(ROOT / "scenarios" / scenario, out=tmp_path / "c", duration="4s", picture=False)
    assert multi.digest == short.digest
