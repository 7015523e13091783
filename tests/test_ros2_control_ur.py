"""A published arm description, driven as its users drive it (issue 48's first done-when
item): Universal Robots' own ur_description, vendored unmodified (tests/robots/
ur_description, 2.4.5: ``ur_mocked.urdf.xacro ur_type:=ur5e name:=ur``: xacro arguments,
``$(find ur_description)``, a ``world`` root link, COLLADA and STL meshes, its own
``<ros2_control>`` block on mock_components/GenericSystem) in a ``robots:`` section, its
controllers file as UR users write it (joints unprefixed) named once in
``robots.controllers``, and a plain rclpy FollowJointTrajectory client as a MoveIt user's
script: SUCCESSFUL within the goal tolerance, INVALID_JOINTS for an unknown joint, a cancel
that leaves the arm holding; one digest for the multi-process run, its in-process replay
and a second in-process run."""

from __future__ import annotations

from control_msgs.action import FollowJointTrajectory
from controller_manager_msgs.srv import ListControllers
from simulation_interfaces.msg import SimulationState

from descriptions.load import load_scenario
from orchestrator.lockstep.inprocess import run_in_process
from orchestrator.outputs.bag import BagReader
from plan.ros_types import message_class
from tests.helpers import ROOT
from tests.sim_client import OK, SimClient, live_runs
from tests.test_ros2_control import ABORTED, CANCELED, SUCCEEDED, TICK_NS, goal, recorded_inputs

SCENARIO = ROOT / "tests" / "scenarios" / "ur5e_control.yaml"
NS = ""  # a lone robot lives at the root: /controller_manager, as UR users run it
JTC = f"{NS}/joint_trajectory_controller/follow_joint_trajectory"
JOINTS = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
          "wrist_2_joint", "wrist_3_joint"]
START = [0.0, -1.57, 0.0, -1.57, 0.0, 0.0]  # config/initial_positions.yaml
TARGET = [0.4, -0.9, 0.7, -0.8, 0.3, 0.5]
GOAL_TOLERANCE = 0.1  # UR's constraints: goal: 0.1 for every joint
FAR = [-0.6, -1.4, 1.2, -1.5, -0.7, -0.9]


def ur_session(sim: SimClient, checks: bool) -> int:
    """What a MoveIt user's script does against the paused run; returns the tick the run
    was stopped before."""
    assert sim.step(5).result == OK
    listed = sim.call(ListControllers, f"{NS}/controller_manager/list_controllers",
                      ListControllers.Request()).controller
    unknown = sim.send_goal(FollowJointTrajectory, JTC, goal(
        [(1.0, [0.0] * 6)], joints=[*JOINTS[:5], "gripper_joint"]))
    assert sim.step(5).result == OK
    refused = sim.result(unknown)
    reached = sim.send_goal(FollowJointTrajectory, JTC, goal(
        [(1.5, [(v + s) / 2 for v, s in zip(TARGET, START, strict=True)]), (2.5, TARGET)],
        joints=JOINTS))  # from where the arm starts (its initial_positions), within 0.2 rad
    assert sim.step(300).result == OK
    success = sim.result(reached)
    slow = sim.send_goal(FollowJointTrajectory, JTC, goal([(3.0, FAR)], joints=JOINTS))
    assert sim.step(80).result == OK
    sim.cancel(slow)
    assert sim.step(2).result == OK
    cancelled = sim.result(slow)
    assert sim.step(40).result == OK  # holding where the cancel left it
    stop = sim.set_state(SimulationState.STATE_STOPPED)
    if checks:
        assert {(c.name, c.type, c.state) for c in listed} == {
            ("joint_state_broadcaster", "joint_state_broadcaster/JointStateBroadcaster",
             "active"),
            ("joint_trajectory_controller",
             "joint_trajectory_controller/JointTrajectoryController", "active")}
        claimed = next(c for c in listed if c.name == "joint_trajectory_controller")
        assert sorted(claimed.claimed_interfaces) == sorted(f"{j}/position" for j in JOINTS)
        assert refused.status == ABORTED
        assert refused.result.error_code == FollowJointTrajectory.Result.INVALID_JOINTS
        assert success.status == SUCCEEDED, success.result.error_string
        assert success.result.error_code == FollowJointTrajectory.Result.SUCCESSFUL
        assert reached.feedback and reached.feedback[-1].joint_names == JOINTS
        assert cancelled.status == CANCELED, cancelled.result.error_string
    return int(stop.error_message.split("before tick ")[1].split()[0])


def test_a_moveit_users_client_drives_urs_own_ur5e_description(tmp_path, ros_node):
    (live,) = live_runs(ros_node, SCENARIO, tmp_path, ur_session, times=1)
    assert live.returncode == 0, live.stderr[-3000:]
    with BagReader(live.run_dir / "bag") as bag:
        states = {s // TICK_NS: dict(zip(m.name, m.position, strict=True))
                  for s, m in bag.messages(f"{NS}/joint_states",
                                           message_class("sensor_msgs/msg/JointState"))}
        entered: dict[str, int] = {}  # goal or cancel name -> the tick it entered
        for s, m in bag.messages(f"{NS}/joint_trajectory_controller/cosim/goal",
                                 message_class("control_msgs/action/FollowJointTrajectory_Goal")):
            entered.setdefault(m.trajectory.header.frame_id, s // TICK_NS)
    goals = sorted(k for n, k in entered.items() if n.startswith("cosim-goal-"))
    (cancel,) = [k for n, k in entered.items() if n.startswith("cosim-cancel-")]
    assert len(goals) == 3  # the unknown joint's goal entered and was refused there
    # the successful goal: every joint within UR's goal tolerance after its 2.5 s
    at = states[goals[1] + 260]
    assert all(abs(at[j] - t) <= GOAL_TOLERANCE for j, t in zip(JOINTS, TARGET, strict=True)), at
    # cancelled mid-motion: the arm holds where it was when the cancel entered, short of FAR
    held, later = states[cancel], states[live.stopped_at - 1]
    assert all(abs(held[j] - later[j]) < 0.02 for j in JOINTS), (held, later)
    assert any(abs(held[j] - f) > 0.2 for j, f in zip(JOINTS, FAR, strict=True)), held

    # in-process, fed what the bag recorded, twice: the multi-process run's digest
    scenario = load_scenario(SCENARIO, {"duration": f"{(live.stopped_at - 1) * 10}ms"})
    inputs = recorded_inputs(live.run_dir, scenario)
    for _ in range(2):
        assert run_in_process(scenario, external=lambda k: inputs.get(k, {})).digest == \
            live.digest
