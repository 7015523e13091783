"""Command-mode switching (issue 48, item 1): a joint whose ``<ros2_control>`` block declares
several command interfaces (UR's position and velocity on every joint) exports them all over
its one MuJoCo actuator, whose mode the hardware switches when a controller claiming another
interface is activated, as ros2_control's ``perform_command_mode_switch``; one command
interface of a joint is claimed at a time. UR's own description, in-process, a few hundred
ticks."""

from __future__ import annotations

import mujoco
import pytest
from std_msgs.msg import Float64MultiArray, String

from descriptions.describe import account
from descriptions.load import load_scenario
from descriptions.urdf import UrdfOptions, load_urdf
from nodes.contract import Tick
from nodes.ros2_control.hardware import hardware_info
from nodes.ros2_control.hosted import MujocoSystem
from nodes.ros2_control.switching import STRICT, plan_switch
from orchestrator.lockstep.inprocess import run_in_process
from orchestrator.ros_surface.controller_hardware import interfaces, manager_hardware
from runtime.build import make_node
from tests.test_ros2_control_hardware import INITIAL, TICK_NS, UR_PACKAGES, UR_XACRO, ur_with

JOINTS = list(INITIAL)
SWITCH = "/controller_manager/cosim/switch"
VELOCITY = "/forward_velocity_controller/commands"
TO_VELOCITY = String(data="#1 -joint_trajectory_controller +forward_velocity_controller")
TO_POSITION = String(data="#2 -forward_velocity_controller +joint_trajectory_controller")
SPEED = 0.5  # rad/s on shoulder_pan_joint (UR's <limit velocity> is pi)


def ur_with_a_velocity_controller(tmp_path, inactive: list[str]):
    """ur5e_control with UR's forward_velocity_controller (ForwardCommandController on
    velocity, as UR's ur_controllers.yaml has it) in its controllers file, its manager
    written as a node (``inactive`` loaded inactive), and a velocity kv for the arm."""

    def edit(doc, controllers):
        doc["robots"]["urdf"]["gains"]["velocity"] = {"kv": 300}
        manager = controllers["controller_manager"]["ros__parameters"]
        manager["forward_velocity_controller"] = {
            "type": "forward_command_controller/ForwardCommandController"}
        controllers["forward_velocity_controller"] = {"ros__parameters": {
            "joints": JOINTS, "interface_name": "velocity"}}

    return ur_with(tmp_path, "ur_modes", inactive, edit)


@pytest.fixture(scope="module")
def scenario(tmp_path_factory):
    path = ur_with_a_velocity_controller(tmp_path_factory.mktemp("modes"),
                                         ["forward_velocity_controller"])
    return load_scenario(path, {"duration": "2500ms"})


def velocity_command() -> Float64MultiArray:
    return Float64MultiArray(data=[SPEED, 0.0, 0.0, 0.0, 0.0, 0.0])


def external(tick: int) -> dict:
    """Velocity mode at tick 10, a command at 11, back to the trajectory controller at 150."""
    return {10: {SWITCH: TO_VELOCITY}, 11: {VELOCITY: velocity_command()},
            150: {SWITCH: TO_POSITION}}.get(tick, {})


def test_the_ur_arms_joints_offer_position_and_velocity(scenario):
    loaded = load_urdf(UR_XACRO, UrdfOptions(args={"ur_type": "ur5e", "name": "ur"},
                                             packages=UR_PACKAGES, env={}))
    assert any("several command interfaces: the actuator (position at the start) switches "
               "mode when a controller claims another" in n for n in loaded.notes)
    assert ("shoulder_pan_joint: revolute [-6.28319, 6.28319], axis 0 0 1, effort 150, "
            "velocity 3.14159: command position or velocity (one actuator, its mode switched "
            "to the interface an activated controller claims) -> actuator "
            "shoulder_pan_joint_position") in account(loaded, UrdfOptions())
    pan = loaded.model.actuated[0]
    assert [m.interface for m in pan.modes] == ["position", "velocity"]
    assert pan.modes[1].ctrlrange == pytest.approx((-3.14159265, 3.14159265))  # <limit velocity>
    command, _ = interfaces(manager_hardware(scenario, "physics", "ur"),
                            ["shoulder_pan_joint/velocity"])
    assert [(i.name, i.is_claimed) for i in command] == [
        (f"{j}/{i}", j == "shoulder_pan_joint" and i == "velocity")
        for j in sorted(JOINTS) for i in ("position", "velocity")]


def test_the_actuator_switches_mode_and_a_recompile_keeps_it():
    loaded = load_urdf(UR_XACRO, UrdfOptions(args={"ur_type": "ur5e", "name": "ur"},
                                             packages=UR_PACKAGES, env={},
                                             gains={"velocity": {"kv": 40.0}}))
    model = loaded.spec.compile()
    data = mujoco.MjData(model)
    info = hardware_info(model, loaded.model)
    joints = [model.joint(j).name for j in range(model.njnt)]
    system = MujocoSystem(model, info, joints, model.jnt_qposadr, model.jnt_dofadr, None)
    system.read(data)
    a = model.actuator("elbow_joint_position").id
    built = (model.actuator_gainprm[a].copy(), model.actuator_biasprm[a].copy())
    system.claim(data, ["elbow_joint/velocity"])
    assert system.mode["elbow_joint"] == "velocity"
    assert model.actuator_gainprm[a, 0] == 40.0
    assert model.actuator_biasprm[a, :3].tolist() == [0.0, 0.0, -40.0]
    assert model.actuator_ctrlrange[a].tolist() == pytest.approx([-3.14159265, 3.14159265])
    system.write(data, {"elbow_joint/velocity": 9.0})
    assert data.ctrl[a] == pytest.approx(3.14159265)  # clamped to <limit velocity>
    again = loaded.spec.compile()  # a robot entering: the world recompiled, its mode kept
    system.bind(again, again.jnt_qposadr, again.jnt_dofadr, None)
    assert again.actuator_biasprm[a, :3].tolist() == [0.0, 0.0, -40.0]
    system.claim(data, ["elbow_joint/position"])
    assert model.actuator_gainprm[a, 0] == 40.0  # the old model, no longer the system's
    assert (again.actuator_gainprm[a] == built[0]).all()
    assert (again.actuator_biasprm[a] == built[1]).all()


def joint_states(out) -> dict[str, float]:
    msg = out["/joint_states"]
    return dict(zip(msg.name, msg.position, strict=True))


def test_a_velocity_controller_moves_the_joint_and_the_trajectory_controller_holds_it(scenario):
    physics = make_node(scenario, "physics")
    states = {}
    for k in range(250):
        states[k] = joint_states(physics.step(Tick(k, k * TICK_NS), external(k)))
        if k == 10:
            metrics = physics.metrics()
            assert metrics["ur/controller_manager/active:forward_velocity_controller"] == 1.0
            assert metrics["ur/controller_manager/active:joint_trajectory_controller"] == 0.0
    # velocity mode: shoulder_pan at about SPEED over a second (from 0.5 s after the
    # command), the others at rest
    moved = states[150]["shoulder_pan_joint"] - states[50]["shoulder_pan_joint"]
    assert moved == pytest.approx(SPEED, rel=0.05)
    assert states[150]["elbow_joint"] == pytest.approx(INITIAL["elbow_joint"], abs=0.05)
    # back to position at tick 150: the trajectory controller holds where the joint was
    held, later = states[151], states[249]
    assert all(abs(held[j] - later[j]) < 0.02 for j in JOINTS), (held, later)
    assert physics.metrics()["ur/controller_manager/active:joint_trajectory_controller"] == 1.0


def test_a_switch_leaves_the_world_other_nodes_and_runs_compile_alone(scenario):
    physics = make_node(scenario, "physics")
    for k in range(12):
        physics.step(Tick(k, k * TICK_NS), external(k))
    model = physics.model
    a = next(i for i in range(model.nu)
             if model.actuator(i).name.endswith("shoulder_pan_joint_position"))
    assert model.actuator_biasprm[a, :3].tolist() == [0.0, 0.0, -300.0]  # velocity mode
    fresh = make_node(scenario, "physics").model  # the process's cached world: as built
    assert fresh.actuator_biasprm[a, :3].tolist() == [0.0, -3000.0, -300.0]


def test_one_digest_with_a_mode_switch(scenario, tmp_path):
    """The switch happens in physics' step at the tick it enters: in-process twice and
    multi-process give one digest (and not the digest of the run without it)."""
    from orchestrator import api

    first = run_in_process(scenario, external=external).digest
    assert run_in_process(scenario, external=external).digest == first
    assert run_in_process(scenario).digest != first
    multi = api.run(scenario, out=tmp_path / "runs", external=external, picture=False)
    assert multi.digest == first


def test_one_command_interface_per_joint_is_claimed(tmp_path):
    from plan.errors import ScenarioError

    # both active from the start: the scenario is refused, naming the joint
    with pytest.raises(ScenarioError) as err:
        load_scenario(ur_with_a_velocity_controller(tmp_path, []))
    assert "joint 'shoulder_pan_joint' would be commanded through" in str(err.value)
    # activated beside the trajectory controller: refused, nothing switched
    scenario = load_scenario(ur_with_a_velocity_controller(tmp_path, [
        "forward_velocity_controller"]), {"duration": "100ms"})
    physics = make_node(scenario, "physics")
    physics.step(Tick(0, 0), {})
    physics.step(Tick(1, TICK_NS), {SWITCH: String(data="#1 +forward_velocity_controller")})
    assert any("one command interface per joint" in n for n in physics.take_notes())
    metrics = physics.metrics()
    assert metrics["ur/controller_manager/refused:1"] == 1.0
    assert metrics["ur/controller_manager/active:forward_velocity_controller"] == 0.0
    # the face refuses it too, as upstream's hardware rejects the mode switch
    states = {"jtc": "active", "fwd": "inactive"}
    claims = {"jtc": ("a/position", "b/position"), "fwd": ("a/velocity", "b/velocity")}
    done = plan_switch(states, claims, ["fwd"], [], STRICT)
    assert not done.ok and "prepare command mode switch was rejected: joint 'a'" in done.message
    assert plan_switch(states, claims, ["fwd"], ["jtc"], STRICT).ok
