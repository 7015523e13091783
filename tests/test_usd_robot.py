"""Robots described in OpenUSD (descriptions/usd_robot.py) load like URDF robots: cosim's two
xacro test robots written in Isaac Sim's importer layout (tools/make_usd_robots.py) and
converted by urdf-usd-converter 0.3.4 and (their MJCF) mujoco-usd-converter 0.8.0
(scenarios/robots/usd/) keep their prims' names, drives
become actuators, the base is free or fixed as the layout says; the same robot from URDF and
from USD follows the same actuator commands to within the stated tolerance; a USD robot
reaches nav's goal, an arm its joint targets, a swarm of copies gives one digest in-process
and multi-process; bad input is exit 2 naming the prim; cosim-describe describes them."""

from __future__ import annotations

import shutil

import mujoco
import numpy as np
import pytest
import yaml

import nodes  # noqa: F401  (the node kinds, for loading scenarios)
from descriptions.load import load_scenario
from descriptions.swarm_world import swarm_model, swarm_spec
from descriptions.urdf import UrdfOptions
from descriptions.usd_robot import load_usd
from orchestrator.api import run
from plan.errors import ScenarioError
from plan.options import RunOptions
from tests.helpers import ROOT

USD = ROOT / "scenarios" / "robots" / "usd"
WHEELS = ("wheel_left_joint", "wheel_right_joint")
ARM = ["shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3"]
ARM_GAINS = {"position": {"kp": 200, "kv": 20}, "wrist_1": {"kp": 30, "kv": 2},
             "wrist_2": {"kp": 30, "kv": 2}, "wrist_3": {"kp": 30, "kv": 2}}


def test_isaac_layout_mobile_robot_reads_as_its_urdf():
    robot = load_usd(USD / "mybot_isaac.usda", UrdfOptions(
        wheels=WHEELS, sensors={"lidar": "base_scan", "imu": "imu_link"})).model
    assert robot.mobile and robot.base_link == "base_footprint" and robot.reader == "usd"
    assert robot.drive.wheel_radius == pytest.approx(0.06)
    assert robot.drive.wheel_separation == pytest.approx(0.40)
    assert {j.name for j in robot.joints} >= {"base_joint", "wheel_left_joint", "scan_joint"}
    assert {k.name for k in robot.links} >= {"base_footprint", "base_link", "imu_link",
                                            "camera_optical_frame", "camera"}
    assert [s.kind for s in robot.sensors] == ["lidar", "camera", "imu"]
    params = dict(robot.sensor("camera").params)  # the UsdGeom.Camera's
    assert params["near"] == pytest.approx(0.05) and params["horizontal_fov"] == \
        pytest.approx(1.047, abs=1e-6)


def test_isaac_layout_drives_become_servos_and_root_joint_fixes_the_arm():
    loaded = load_usd(USD / "myarm_isaac.usda")
    robot, model = loaded.model, loaded.spec.compile()
    assert not robot.mobile and [a.joint for a in robot.actuated] == ARM
    assert {a.interface for a in robot.actuated} == {"position"}
    elbow = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, "elbow_position")
    assert model.actuator_gainprm[elbow, 0] == pytest.approx(200, rel=1e-6)  # per degree in
    assert model.actuator_biasprm[elbow, 2] == pytest.approx(-20, rel=1e-6)  # USD, per rad
    assert model.actuator_forcerange[elbow].tolist() == pytest.approx([-40, 40])
    joint = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "elbow")
    assert model.jnt_range[joint].tolist() == pytest.approx([-2.6, 2.6], abs=1e-6)  # degrees


def test_colliders_in_an_instanceable_prim_are_read(tmp_path):
    """Isaac's importer makes a link's meshes instanceable references: the colliders are
    instance proxies, which a plain prim traversal does not enter."""
    from pxr import Sdf, Usd

    stage = Usd.Stage.Open(str(USD / "mybot_isaac.usda"))
    layer = stage.GetRootLayer()
    Sdf.CopySpec(layer, "/mybot/wheel_left_link/collisions", layer, "/WheelCollisions")
    stage.RemovePrim("/mybot/wheel_left_link/collisions")
    group = stage.DefinePrim("/mybot/wheel_left_link/collisions", "Xform")
    group.GetReferences().AddInternalReference("/WheelCollisions")
    group.SetInstanceable(True)
    layer.Export(str(tmp_path / "instanced.usda"))
    model = load_usd(tmp_path / "instanced.usda", UrdfOptions(wheels=WHEELS)).spec.compile()
    assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM,
                             "wheel_left_link_collision_0") >= 0


def test_urdf_usd_converter_layout_keeps_frames_sensors_and_ros2_control():
    bot = load_usd(USD / "mybot_urdf_usd_converter.usda", UrdfOptions(wheels=WHEELS)).model
    assert bot.mobile and bot.base_link == "base_footprint"  # a plain Xform above base_link
    assert {"imu_link", "camera_optical_frame"} <= {k.name for k in bot.links}
    assert {s.kind: s.link for s in bot.sensors} == {"lidar": "base_scan",
                                                     "camera": "camera_link", "imu": "imu_link"}
    assert any("newton:inertia both given" in n for n in bot.notes)
    arm = load_usd(USD / "myarm_urdf_usd_converter.usda").model
    assert not arm.mobile  # its root_joint
    assert [(a.joint, a.interface) for a in arm.actuated][-2:] == [("wrist_2", "velocity"),
                                                                  ("wrist_3", "effort")]


def test_mujoco_usd_converter_layout_reads_mjc_actuators():
    arm = load_usd(USD / "myarm_mujoco_usd_converter.usda")
    assert not arm.model.mobile and [a.joint for a in arm.model.actuated] == ARM
    model = arm.spec.compile()
    wrist = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, "wrist_3_position")
    assert model.actuator_gainprm[wrist, 0] == pytest.approx(30)  # MjcActuator gain, bias
    assert model.actuator_biasprm[wrist, 1:3].tolist() == pytest.approx([-30, -2])
    bot = load_usd(USD / "mybot_mujoco_usd_converter.usda", UrdfOptions(wheels=WHEELS))
    assert bot.model.mobile and bot.model.drive.wheel_radius == pytest.approx(0.06)
    assert {j.name for j in bot.model.joints} >= {"wheel_left_joint", "imu_link_joint"}
    assert any("PhysicsFixedJoint" in n or "named by their child" in n for n in bot.notes)


def _swap(tmp_path, scenario: str, description: str, usd: dict | None, name: str):
    doc = yaml.safe_load((ROOT / "scenarios" / scenario).read_text())
    doc["robots"]["description"] = str(USD / description)
    doc["robots"].pop("urdf", None)
    if usd is not None:
        doc["robots"]["usd"] = usd
    path = tmp_path / name
    path.write_text(yaml.safe_dump(doc))
    shutil.copytree(ROOT / "scenarios" / "worlds", tmp_path / "worlds", dirs_exist_ok=True)
    return path


def _follow(path, commands, steps: int, record, undamped: tuple[str, ...] = ()) -> np.ndarray:
    """The recorded state over ``steps`` steps of the scenario's world under ``commands``
    (step -> {actuator: ctrl}); the ``undamped`` joints' damping set to 0 first."""
    scenario = load_scenario(path)
    if undamped:
        spec = swarm_spec(scenario.world, scenario.robots)
        for joint in undamped:
            spec.joint(joint).damping = [0.0, 0.0, 0.0]
        model = spec.compile()
    else:
        model = swarm_model(scenario.world, scenario.robots)
    data = mujoco.MjData(model)
    out = []
    for k in range(steps):
        for actuator, value in commands(k).items():
            data.ctrl[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, actuator)] = value
        mujoco.mj_step(model, data)
        out.append(record(model, data))
    return np.array(out)


def test_the_same_mobile_robot_from_urdf_and_usd_follows_the_same_wheel_commands(tmp_path):
    """4 s of the same wheel speeds (a left then a right turn, 1.2 m): from either converter's
    layout the base follows the URDF robot's path to 1e-6 m. From Isaac's layout it is 4.2 cm
    off, all of it the URDF's wheel <dynamics damping="0.01">, which Isaac's layout has no
    place for: without it the URDF robot follows the same path to 1e-6 m."""
    def wheels(k):
        turn = 0.5 if k < 1000 else -0.5
        return {"mybot/wheel_left_joint_velocity": (0.3 - 0.2 * turn) / 0.06,
                "mybot/wheel_right_joint_velocity": (0.3 + 0.2 * turn) / 0.06}

    def base(model, data):
        return data.xpos[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY,
                                           "mybot/base_footprint")].copy()

    nav_urdf = ROOT / "scenarios" / "nav_urdf.yaml"
    urdf = _follow(nav_urdf, wheels, 2000, base)
    isaac = _follow(ROOT / "scenarios" / "nav_usd_robot.yaml", wheels, 2000, base)
    assert np.linalg.norm(urdf[-1] - urdf[0]) > 1.0
    assert np.abs(urdf - isaac).max() < 0.05
    undamped = _follow(nav_urdf, wheels, 2000, base, tuple(f"mybot/{w}" for w in WHEELS))
    assert np.abs(undamped - isaac).max() < 1e-6
    for layout in ("urdf_usd_converter", "mujoco_usd_converter"):  # the damping kept
        converted = _follow(_swap(tmp_path, "nav_usd_robot.yaml", f"mybot_{layout}.usda", None,
                                  f"nav_{layout}.yaml"), wheels, 2000, base)
        assert np.abs(urdf - converted).max() < 1e-6, layout


def test_the_same_arm_from_urdf_and_usd_follows_the_same_position_commands(tmp_path):
    """Two targets held 2 s each. Isaac's layout (no joint damping: the URDF's 0.5 and 0.2
    N m s/rad have no place there) settles on the same positions (1e-4 rad) by other
    transients (up to 0.6 rad apart on the light wrist), and follows the undamped URDF arm
    to 1e-6 rad; urdf-usd-converter's and mujoco-usd-converter's (newton:damping kept)
    follow the URDF arm the whole way (1e-6 rad)."""
    targets = [[0.8, -0.5, 1.0, 0.0, 0.5, 0.0], [0.0, 0.6, 0.8, -0.4, 0.0, 1.0]]

    def command(k):
        return {f"myarm/{j}_position": v for j, v in zip(ARM, targets[k >= 1000], strict=True)}

    def joints(model, data):
        return [data.qpos[model.jnt_qposadr[mujoco.mj_name2id(
            model, mujoco.mjtObj.mjOBJ_JOINT, f"myarm/{j}")]] for j in ARM]

    urdf = _follow(ROOT / "scenarios" / "arm_urdf.yaml", command, 2000, joints)
    isaac = _follow(ROOT / "scenarios" / "arm_usd.yaml", command, 2000, joints)
    undamped = _follow(ROOT / "scenarios" / "arm_urdf.yaml", command, 2000, joints,
                       tuple(f"myarm/{j}" for j in ARM))
    assert np.abs(undamped - isaac).max() < 1e-6
    converted = _follow(_swap(tmp_path, "arm_urdf.yaml", "myarm_urdf_usd_converter.usda", {
        "interfaces": {"wrist_2": "position", "wrist_3": "position"}, "gains": ARM_GAINS},
        "arm_converted.yaml"), command, 2000, joints)
    for settled in (999, 1999):
        assert urdf[settled] == pytest.approx(targets[settled > 999], abs=0.05)
        assert isaac[settled] == pytest.approx(urdf[settled], abs=1e-4)
    assert np.abs(converted - urdf).max() < 1e-6
    mujoco_layout = _follow(_swap(tmp_path, "arm_usd.yaml", "myarm_mujoco_usd_converter.usda",
                                  None, "arm_mujoco.yaml"), command, 2000, joints)
    assert np.abs(mujoco_layout - urdf).max() < 1e-6


LAYOUTS = ("isaac", "urdf_usd_converter", "mujoco_usd_converter")
# urdf-usd-converter's arm has no drives; its kept <ros2_control> commands wrist_2 by velocity
# and wrist_3 by effort, so the scenario makes them position servos with arm_urdf.yaml's gains
# (as arm_urdf.yaml does for the xacro), and one position vector commands all six.
ARM_COMMANDS = {"urdf_usd_converter": {"robots.usd": {
    "interfaces": {"wrist_2": "position", "wrist_3": "position"}, "gains": ARM_GAINS}}}
ARMS = [{"name": f"arm_{i}", "start": {"x": 0.0, "y": y}, "goal": {"x": 0.0, "y": y}}
        for i, y in enumerate((1.5, -1.5))]
LAST_TARGET = [-0.6, 0.4, 1.1, 0.5, -0.8, 0.3]


@pytest.mark.parametrize("layout", LAYOUTS)
def test_usd_robots_of_each_layout_reach_their_goals_alone_and_in_a_swarm(tmp_path, layout):
    """nav_usd_robot.yaml and arm_usd.yaml with their robot in each layout (the ``--set
    robots.description=robots/usd/..._LAYOUT.usda`` a user would give), in-process: the diff
    drive reaches nav's goal, the arm (alone, at the root, and two copies) its third target."""
    nav = run(ROOT / "scenarios" / "nav_usd_robot.yaml", in_process=True, out=tmp_path,
              overrides={"robots.description": f"robots/usd/mybot_{layout}.usda"}, picture=False)
    assert nav.success and nav.metrics["mybot/arrived"] == 1.0
    assert nav.last("/joint_states").name == list(WHEELS)  # a lone robot: at the root
    description = nav.last("/robot_description").data
    assert "<robot name=\"mybot\">" in description and ".stl\"" in description
    assert "usd-robots" not in description  # no machine's path: one digest everywhere
    arm_usd = ROOT / "scenarios" / "arm_usd.yaml"
    arm = {"robots.description": f"robots/usd/myarm_{layout}.usda",
           **ARM_COMMANDS.get(layout, {})}
    alone = run(arm_usd, in_process=True, out=tmp_path, overrides=arm, picture=False)
    assert alone.metrics["target"] == 2.0  # the third of three reached
    states = alone.last("/joint_states")
    assert states.name == ARM
    assert list(states.position) == pytest.approx(LAST_TARGET, abs=0.05)
    swarm = run(arm_usd, in_process=True, out=tmp_path, overrides={**arm, "robots.named": ARMS},
                picture=False)
    for name in ("arm_0", "arm_1"):
        assert swarm.metrics_by_node[f"arm@{name}"]["target"] == 2.0, name
        assert list(swarm.last(f"/{name}/joint_states").position) == pytest.approx(
            LAST_TARGET, abs=0.05)


@pytest.mark.parametrize("layout", LAYOUTS)
def test_a_swarm_of_usd_robots_gives_one_digest_in_process_and_multi_process(tmp_path, layout):
    """Two copies of the diff drive in each layout, placed by the seed (count:), for 1 s,
    and two copies of the arm for 0.5 s: one digest in-process and multi-process (packed by
    kind: the digest does not depend on the packing, and three processes start faster than
    five on two cores)."""
    overrides = {"robots.description": f"robots/usd/mybot_{layout}.usda",
                 "robots.named": None, "robots.count": 2, "robots.name_prefix": "bot",
                 "robots.region": {"x": [-3, 3], "y": [-3, 3]}}
    nav_usd = ROOT / "scenarios" / "nav_usd_robot.yaml"
    one = run(nav_usd, in_process=True, out=tmp_path, duration="1s", overrides=overrides,
              picture=False)
    many = run(nav_usd, out=tmp_path, duration="1s", overrides=overrides,
               options=RunOptions(pack="kind"), picture=False)
    assert one.digest == many.digest and one.ticks == 51
    static = {(t.header.frame_id, t.child_frame_id)
              for t in one.last("/tf_static").transforms}
    assert {("bot_1/base_link", "bot_1/imu_link"), ("bot_0/base_link", "bot_0/base_scan")} \
        <= static
    arms = {"robots.description": f"robots/usd/myarm_{layout}.usda", "robots.named": ARMS,
            **ARM_COMMANDS.get(layout, {})}
    arm_usd = ROOT / "scenarios" / "arm_usd.yaml"
    one = run(arm_usd, in_process=True, out=tmp_path, duration="0.5s", overrides=arms,
              picture=False)
    many = run(arm_usd, out=tmp_path, duration="0.5s", overrides=arms,
               options=RunOptions(pack="kind"), picture=False)
    assert one.digest == many.digest and one.last("/arm_1/joint_states").name == ARM


def _broken(tmp_path, source: str, edit) -> str:
    from pxr import Usd

    stage = Usd.Stage.Open(str(USD / source))
    edit(stage)
    out = tmp_path / source
    stage.GetRootLayer().Export(str(out))
    return str(out)


@pytest.mark.parametrize("source, edit, usd, words", [
    ("mybot_isaac.usda",
     lambda s: s.GetPrimAtPath("/mybot/joints/wheel_left_joint").GetRelationship(
         "physics:body1").SetTargets(["/mybot/wheel_gone"]),
     {"wheels": list(WHEELS)},
     "prim /mybot/joints/wheel_left_joint: physics:body1 names /mybot/wheel_gone"),
    ("myarm_urdf_usd_converter.usda",
     lambda s: s.RemovePrim("/myarm/Geometry/custom"),
     {"gains": {"elbow": {"kp": 50}}},
     "joint 'elbow', prim /myarm/Physics/elbow: the joint is driven"),
    ("myarm_isaac.usda",
     lambda s: (s.RemovePrim("/myarm/root_joint"),
                s.GetPrimAtPath("/myarm").RemoveAPI("PhysicsArticulationRootAPI")),
     None, "prim /myarm/base_link: the robot has no root"),
])
def test_bad_usd_robots_are_exit_2_naming_the_prim(tmp_path, source, edit, usd, words):
    from pxr import UsdPhysics

    assert UsdPhysics  # the schemas registered before the stage is edited
    doc = yaml.safe_load((ROOT / "scenarios" / "arm_usd.yaml").read_text())
    doc["robots"]["description"] = _broken(tmp_path, source, edit)
    if usd is not None:
        doc["robots"]["usd"] = usd
    doc["world"] = str(ROOT / "scenarios" / "worlds" / "arena.xml")
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(doc))
    with pytest.raises(ScenarioError) as err:
        load_scenario(path)
    assert "robots.description" in str(err.value) and words in str(err.value)


def test_cosim_describe_describes_a_usd_robot(capsys):
    from descriptions.describe import main

    assert main([str(USD / "myarm_isaac.usda")]) == 0
    out = capsys.readouterr().out
    assert "robot 'myarm' from" in out and "fixed to the world" in out
    assert "elbow: revolute [-2.6, 2.6]" in out and "actuator elbow_position" in out
    assert main([str(USD / "nowhere.usda")]) == 2
    assert main([str(ROOT / "scenarios" / "swarm_usd_robots.yaml")]) == 0  # the stage's robot
    assert "mybot_isaac.usda" in capsys.readouterr().out


def test_the_load_says_what_the_usd_robot_lost_and_settings_go_with_their_format(tmp_path,
                                                                                 capsys):
    doc = yaml.safe_load((ROOT / "scenarios" / "nav_usd_robot.yaml").read_text())
    doc["robots"]["description"] = str(USD / "mybot_mujoco_usd_converter.usda")
    doc["robots"]["usd"]["base"] = "free"
    doc["world"] = str(ROOT / "scenarios" / "worlds" / "arena.xml")
    path = tmp_path / "said.yaml"
    path.write_text(yaml.safe_dump(doc))
    load_scenario(path)
    said = capsys.readouterr().err
    assert "mybot_mujoco_usd_converter.usda read as a USD robot; changed or not kept:" in said
    assert "applied schemas not read: MjcCollisionAPI" in said
    doc["robots"]["urdf"] = {"wheels": list(WHEELS)}
    path.write_text(yaml.safe_dump(doc))
    with pytest.raises(ScenarioError, match="robots.urdf: urdf: settings for a USD"):
        load_scenario(path)
    doc["robots"].pop("urdf")
    doc["nodes"][1]["params"] = {"lidar": {}}
    doc["robots"]["usd"] = {"wheels": list(WHEELS), "sensors": {"imu": "imu_link"}}
    doc["robots"]["description"] = str(USD / "mybot_isaac.usda")
    path.write_text(yaml.safe_dump(doc))
    with pytest.raises(ScenarioError, match=r"add robots.usd.sensors: \{lidar: PRIM\}"):
        load_scenario(path)


def slider_stage(tmp_path, lower=-50.0, upper=50.0):
    """A stage in centimetres with +Y up: a base fixed to the world and a carriage on a
    prismatic rail (limits ``lower``, ``upper`` in cm; None: not given) with a linear drive;
    its stage (saved as slider.usda)."""
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdPhysics

    stage = Usd.Stage.CreateNew(str(tmp_path / "slider.usda"))
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    root = UsdGeom.Xform.Define(stage, "/slider").GetPrim()
    stage.SetDefaultPrim(root)
    UsdPhysics.ArticulationRootAPI.Apply(root)
    for name, y, inertia in (("base", 0.0, 200.0), ("carriage", 30.0, 100.0)):
        link = UsdGeom.Xform.Define(stage, f"/slider/{name}")
        link.AddTranslateOp().Set(Gf.Vec3d(0, y, 0))
        UsdPhysics.RigidBodyAPI.Apply(link.GetPrim())
        mass = UsdPhysics.MassAPI.Apply(link.GetPrim())
        mass.CreateMassAttr(2.0 if name == "base" else 1.0)
        mass.CreateDiagonalInertiaAttr(Gf.Vec3f(inertia, inertia, inertia))
    UsdPhysics.CollisionAPI.Apply(UsdGeom.Cube.Define(stage, "/slider/base/box").GetPrim())
    stage.GetPrimAtPath("/slider/base/box").GetAttribute("size").Set(20.0)
    capsule = UsdGeom.Capsule.Define(stage, "/slider/carriage/shape")
    capsule.CreateRadiusAttr(5.0)
    capsule.CreateHeightAttr(10.0)
    capsule.CreateAxisAttr("X")
    UsdPhysics.CollisionAPI.Apply(capsule.GetPrim())
    UsdPhysics.FixedJoint.Define(stage, "/slider/root_joint").CreateBody1Rel().SetTargets(
        [Sdf.Path("/slider/base")])
    rail = UsdPhysics.PrismaticJoint.Define(stage, "/slider/rail")
    rail.CreateAxisAttr("X")
    rail.CreateBody0Rel().SetTargets([Sdf.Path("/slider/base")])
    rail.CreateBody1Rel().SetTargets([Sdf.Path("/slider/carriage")])
    rail.CreateLocalPos0Attr(Gf.Vec3f(0, 30, 0))
    if lower is not None:
        rail.CreateLowerLimitAttr(lower)
    if upper is not None:
        rail.CreateUpperLimitAttr(upper)
    drive = UsdPhysics.DriveAPI.Apply(rail.GetPrim(), "linear")
    drive.CreateStiffnessAttr(400.0)
    drive.CreateDampingAttr(40.0)
    drive.CreateMaxForceAttr(1000.0)  # kg cm / s^2: 10 N
    stage.GetRootLayer().Save()
    return stage


def test_a_centimetre_y_up_robot_with_a_prismatic_drive_reads_in_si_units(tmp_path):
    """A stage in centimetres with +Y up: lengths, inertias and the drive's force limit in
    SI, a linear drive's gains as they are (force per length), the slide along its axis."""
    slider_stage(tmp_path)

    loaded = load_usd(tmp_path / "slider.usda")
    model = loaded.spec.compile()
    assert not loaded.model.mobile and [(a.joint, a.interface) for a in
                                        loaded.model.actuated] == [("rail", "position")]

    def named(kind, name):
        return mujoco.mj_name2id(model, kind, name)

    rail_id = named(mujoco.mjtObj.mjOBJ_JOINT, "rail")
    assert model.jnt_type[rail_id] == mujoco.mjtJoint.mjJNT_SLIDE
    assert model.jnt_range[rail_id].tolist() == pytest.approx([-0.5, 0.5])
    assert model.jnt_axis[rail_id].tolist() == pytest.approx([1, 0, 0])
    carriage = named(mujoco.mjtObj.mjOBJ_BODY, "carriage")
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    assert data.xpos[carriage].tolist() == pytest.approx([0, 0, 0.3])  # +Y up is +Z
    assert model.body_inertia[carriage].tolist() == pytest.approx([0.01] * 3)
    act = named(mujoco.mjtObj.mjOBJ_ACTUATOR, "rail_position")
    assert model.actuator_gainprm[act, 0] == pytest.approx(400)
    assert model.actuator_biasprm[act, 2] == pytest.approx(-40)
    assert model.actuator_forcerange[act].tolist() == pytest.approx([-10, 10])
    shape = named(mujoco.mjtObj.mjOBJ_GEOM, "carriage_collision_0")
    assert model.geom_type[shape] == mujoco.mjtGeom.mjGEOM_CAPSULE
    assert model.geom_size[shape, :2].tolist() == pytest.approx([0.05, 0.05])
    box = named(mujoco.mjtObj.mjOBJ_GEOM, "base_collision_0")
    assert model.geom_size[box].tolist() == pytest.approx([0.1, 0.1, 0.1])


def test_a_stage_referencing_a_usd_robot_runs_one_copy_per_prim(tmp_path):
    """Prims referencing the robot asset, as Isaac Sim's add_reference_to_stage places them
    (scenarios/worlds/swarm_usd_robots.usda): one robot per prim, named and placed by it;
    without a robots: section the prim is named as the problem."""
    scenario = ROOT / "scenarios" / "swarm_usd_robots.yaml"
    loaded = load_scenario(scenario)
    assert loaded.robots.description == USD / "mybot_isaac.usda"
    starts = {r.name: r.start for r in loaded.robots.robots}
    assert starts["robot_0"][:2] == pytest.approx((2.96, 1.22))
    swarm = swarm_model(loaded.world, loaded.robots)
    assert mujoco.mj_name2id(swarm, mujoco.mjtObj.mjOBJ_JOINT, "robot_7/wheel_left_joint") >= 0
    assert not [swarm.body(b).name for b in range(swarm.nbody)
                if swarm.body(b).name.startswith("/World/Robots")]  # not imported by MuJoCo
    result = run(scenario, in_process=True, out=tmp_path, duration="0.2s", picture=False)
    assert result.ticks == 11 and result.last("/robot_3/odom") is not None
    doc = yaml.safe_load(scenario.read_text())
    doc.pop("robots")
    doc.update(goal={"x": 1.0, "y": 1.0}, world=str(ROOT / "scenarios" / "worlds" /
                                                    "swarm_usd_robots.usda"))
    for node in doc["nodes"]:
        node.pop("for_each", None)
    path = tmp_path / "no_robots.yaml"
    path.write_text(yaml.safe_dump(doc))
    with pytest.raises(ScenarioError, match="prim /World/Robots/robot_0: the prim references "
                                            "a robot described in USD"):
        load_scenario(path)


def test_a_one_sided_limit_and_a_geared_actuator_are_said_or_refused(tmp_path):
    """URDF has no one-sided limit: a rail limited above only is limited far below, and the
    load says so; a mujoco-usd-converter actuator with a gear other than 1 is exit 2 naming
    its prim (its gains would be the actuator's, not the joint's)."""
    from pxr import Sdf

    from descriptions.description_error import DescriptionError

    stage = slider_stage(tmp_path, lower=None, upper=20.0)
    model = load_usd(tmp_path / "slider.usda").spec.compile()
    rail = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "rail")
    assert model.jnt_range[rail].tolist() == pytest.approx([-1e6, 0.2])
    actuator = stage.DefinePrim("/slider/rail_motor", "MjcActuator")
    actuator.CreateRelationship("mjc:target").SetTargets(["/slider/rail"])
    actuator.CreateAttribute("mjc:gear", Sdf.ValueTypeNames.DoubleArray).Set([2.0])
    stage.GetRootLayer().Save()
    with pytest.raises(DescriptionError, match=r"prim /slider/rail_motor: .*mjc:gear 2"):
        load_usd(tmp_path / "slider.usda")
