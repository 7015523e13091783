"""The `<ros2_control>` block's params and interfaces as cosim's hardware takes them: a state
interface's ``initial_value`` is where the joint starts (at the first tick and after every
reset, as mock_components and gz_ros2_control start it), a command interface's ``min``/
``max`` clamps what the hardware writes, and list_hardware_interfaces lists what the block
declares. In-process, a few ticks: no ROS traffic."""

from __future__ import annotations

import mujoco
import pytest

from descriptions.load import load_scenario
from descriptions.urdf import UrdfOptions, load_urdf
from nodes.contract import Tick
from nodes.physics.world import start_joints
from nodes.ros2_control.hardware import hardware_info
from nodes.ros2_control.hosted import MujocoSystem
from orchestrator.ros_surface.controller_hardware import interfaces, manager_hardware
from runtime.activation import Activation
from runtime.build import make_node
from tests.helpers import ROOT

UR = ROOT / "tests" / "scenarios" / "ur5e_control.yaml"
ARM = ROOT / "scenarios" / "robots" / "myarm_description" / "urdf" / "myarm.urdf.xacro"
UR_XACRO = ROOT / "tests" / "robots" / "ur_description" / "urdf" / "ur_mocked.urdf.xacro"
UR_PACKAGES = {"ur_description": str(ROOT / "tests" / "robots" / "ur_description")}
PACKAGES = {"myarm_description": str(ROOT / "scenarios" / "robots" / "myarm_description")}
# tests/robots/ur_description/config/initial_positions.yaml, as UR's mock hardware starts
INITIAL = {"shoulder_pan_joint": 0.0, "shoulder_lift_joint": -1.57, "elbow_joint": 0.0,
           "wrist_1_joint": -1.57, "wrist_2_joint": 0.0, "wrist_3_joint": 0.0}
TICK_NS = 10_000_000


@pytest.fixture(scope="module")
def ur():
    return load_scenario(UR, {"duration": "100ms"})


def joint_states(out) -> dict[str, float]:
    msg = out["/joint_states"]
    return dict(zip(msg.name, msg.position, strict=True))


def test_the_ur_arm_starts_at_its_initial_positions_and_a_reset_puts_it_back(ur):
    node = make_node(ur, "physics")
    run = Activation(ur.nodes["physics"], node)
    first = joint_states(node.step(Tick(0, 0), {}))
    assert first == pytest.approx(INITIAL, abs=1e-12)  # set, not reached
    for k in range(1, 6):  # held there by the trajectory controller's hold at activation
        held = joint_states(node.step(Tick(k, k * TICK_NS), {}))
    assert held == pytest.approx(INITIAL, abs=0.02)
    node.data.qpos[:] += 0.3  # somewhere else, as a run that moved the arm
    moved = joint_states(node.step(Tick(6, 6 * TICK_NS), {}))
    assert moved != pytest.approx(INITIAL, abs=0.1)
    run.restart(ur.model.seed)  # what ResetSimulation does to every node
    again = joint_states(run.node.step(Tick(0, 0), {}))
    assert again == first


def test_the_initial_values_are_in_the_robot_model_and_set_with_the_servos_target():
    loaded = load_urdf(UR_XACRO, UrdfOptions(args={"ur_type": "ur5e", "name": "ur"},
                                             packages=UR_PACKAGES, env={}))
    robot = loaded.model
    assert {c.joint: c.initial for c in robot.control} == {
        j: (("position", v), ("velocity", 0.0)) for j, v in INITIAL.items()}
    assert robot.scoped("ur").control[0].joint == "ur/shoulder_pan_joint"
    model = loaded.spec.compile()
    data = mujoco.MjData(model)
    start_joints(model, data, (robot,))  # no controller manager: /joint_commands' servos
    for joint, value in INITIAL.items():
        assert data.qpos[model.joint(joint).qposadr[0]] == value
        assert data.ctrl[model.actuator(f"{joint}_position").id] == value


def test_the_hardware_clamps_a_command_to_the_blocks_min_and_max():
    loaded = load_urdf(ARM, UrdfOptions(packages=PACKAGES, env={}))
    model = loaded.spec.compile()
    data = mujoco.MjData(model)
    info = hardware_info(model, loaded.model)
    joints = [model.joint(j).name for j in range(model.njnt)]
    system = MujocoSystem(model, info, joints, model.jnt_qposadr, model.jnt_dofadr, None)
    system.write(data, {"wrist_3/effort": 5.0, "elbow/position": -9.0,
                        "shoulder_pan/position": 0.25})
    act = lambda name: mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, name)  # noqa: E731
    assert data.ctrl[act("wrist_3_effort")] == 2.0  # <param name="max">2</param>
    assert data.ctrl[act("elbow_position")] == pytest.approx(-2.6)  # the joint's <limit>
    assert data.ctrl[act("shoulder_pan_position")] == 0.25


def test_list_hardware_interfaces_lists_what_the_block_declares(ur):
    hardware = manager_hardware(ur, "physics", "ur")
    command, state = interfaces(hardware, ["shoulder_pan_joint/position"])
    # UR's block offers position and velocity commands: both listed (the joint's actuator
    # switches to the one an activated controller claims)
    assert [(i.name, i.is_claimed) for i in command] == [
        (f"{j}/{i}", j == "shoulder_pan_joint" and i == "position")
        for j in sorted(INITIAL) for i in ("position", "velocity")]
    # the block declares position, velocity and effort state interfaces (its <sensor>s,
    # tcp_fts_sensor and tcp_pose, are not simulated: no interfaces)
    assert [i.name for i in state] == [f"{j}/{i}" for j in sorted(INITIAL)
                                       for i in ("effort", "position", "velocity")]


def test_physics_does_not_build_the_joint_states_a_broadcaster_replaces(ur, monkeypatch):
    import nodes.physics.batch as batch

    def built(*args):
        raise AssertionError("physics built /joint_states a broadcaster publishes")

    node = make_node(ur, "physics")
    monkeypatch.setattr(batch.fm, "joint_state", built)
    out = node.step(Tick(0, 0), {})
    assert sorted(out["/joint_states"].name) == sorted(INITIAL)  # the broadcaster's


def ur_with(tmp_path, name: str, inactive: list[str], edit):
    """ur5e_control with its manager written as a node (``inactive`` loaded inactive), its
    scenario and controllers file as ``edit(doc, controllers)`` changes them; written in
    ``tmp_path`` as NAME.yaml, its path."""
    import yaml

    doc = yaml.safe_load(UR.read_text())
    here = UR.parent
    doc["world"] = str((here / doc["world"]).resolve())
    robots = doc["robots"]
    robots["description"] = str((here / robots["description"]).resolve())
    robots["urdf"]["packages"] = UR_PACKAGES
    controllers = yaml.safe_load((here / robots.pop("controllers")).read_text())
    edit(doc, controllers)
    (tmp_path / "controllers.yaml").write_text(yaml.safe_dump(controllers))
    params = {"controllers": str(tmp_path / "controllers.yaml"), "inactive": inactive}
    doc["nodes"].append({"name": "controller_manager", "kind": "ros2_control", "rate": 100,
                         "for_each": "robot", "params": params})
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def ur_with_an_acceleration_controller(tmp_path, inactive: list[str]):
    """ur5e_control with its manager written as a node, its file given a second trajectory
    controller reading acceleration, which the arm's block does not declare."""

    def edit(doc, controllers):
        manager = controllers["controller_manager"]["ros__parameters"]
        manager["accel_jtc"] = {"type": "joint_trajectory_controller/JointTrajectoryController"}
        jtc = controllers["joint_trajectory_controller"]["ros__parameters"]
        controllers["accel_jtc"] = {"ros__parameters": {
            **jtc, "state_interfaces": ["position", "velocity", "acceleration"]}}

    return ur_with(tmp_path, "ur_accel", inactive, edit)


def test_a_state_interface_the_block_does_not_declare_is_refused(tmp_path):
    from std_msgs.msg import String

    from plan.errors import ScenarioError

    lacks = "joint 'shoulder_pan_joint' has no acceleration state interface"
    # active from the start: the scenario is refused, naming the controller and interface
    with pytest.raises(ScenarioError) as err:
        load_scenario(ur_with_an_acceleration_controller(tmp_path, ["joint_trajectory_"
                                                                    "controller"]))
    assert f"accel_jtc: {lacks}" in str(err.value)
    # loaded inactive: it loads, and its activation is refused, as upstream's
    scenario = load_scenario(ur_with_an_acceleration_controller(tmp_path, ["accel_jtc"]),
                             {"duration": "100ms"})
    physics = make_node(scenario, "physics")
    physics.step(Tick(0, 0), {})
    assert any(n.startswith(f"accel_jtc: {lacks}") for n in physics.take_notes())
    switch = String(data="#1 -joint_trajectory_controller +accel_jtc")
    physics.step(Tick(1, TICK_NS), {"/controller_manager/cosim/switch": switch})
    notes = physics.take_notes()
    assert any(f"controller 'accel_jtc' cannot be activated: {lacks}" in n for n in notes)
    metrics = physics.metrics()
    assert metrics["ur/controller_manager/refused:1"] == 1.0
    assert metrics["ur/controller_manager/active:accel_jtc"] == 0.0
    assert metrics["ur/controller_manager/active:joint_trajectory_controller"] == 1.0
