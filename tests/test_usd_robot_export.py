"""--export-usd writes a URDF or USD robot under its own link and joint names in Isaac Sim's
importer layout (descriptions/usd_robot_write.py, robots/ROBOT.usda beside run.usda), and the
file runs again as the same robot (descriptions/usd_robot.py reads it).

The round trip is checked by trajectories, not by digest: the compiled model of the robot read
back is never bit-identical to the original (USD stores masses, inertia, drive gains, limits
and local frames as 32-bit floats, gains and limits per degree; measured: at most 1e-7
relative), and its /robot_description is the URDF the USD reader writes. Over 2 s the joint
positions and the odometry of the robot read back stay within 1e-6 (rad, m) of the original
(measured: 9e-10 for the diff drive's wheels and odometry, 1.5e-8 rad for the arm)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
import yaml

import nodes  # noqa: F401  (the node kinds, for loading scenarios)
from descriptions.load import load_scenario
from descriptions.readers import load_robot
from descriptions.swarm_world import swarm_model
from descriptions.urdf import UrdfOptions
from descriptions.usd_robot import load_usd
from descriptions.usd_robot_write import write_robot_usd
from orchestrator.api import run
from plan.options import RunOptions
from tests.helpers import ROOT

SCENARIOS = ROOT / "scenarios"
USD = SCENARIOS / "robots" / "usd"
WHEELS = ("wheel_left_joint", "wheel_right_joint")
TOLERANCE = 1e-6  # rad and m over 2 s; see the module's docstring
COMPARED = ("body_pos", "body_mass", "body_inertia", "body_ipos", "jnt_axis",
            "jnt_range", "dof_damping", "actuator_gainprm", "actuator_biasprm",
            "actuator_forcerange", "actuator_ctrlrange", "geom_size", "geom_friction",
            "geom_priority", "geom_contype", "geom_type", "geom_pos", "geom_rgba", "jnt_pos")
SIGNLESS = ("body_quat", "body_iquat")  # q and -q are one rotation


def _loaded(scenario: str):
    robots = load_scenario(SCENARIOS / scenario).robots
    return load_robot(robots.description, robots.settings)


def _joints(model):
    return [(j.name, j.kind, j.parent, j.child) for j in model.joints]


@pytest.mark.parametrize("scenario, wheels", [
    ("nav_urdf.yaml", WHEELS), ("arm_urdf.yaml", None),
    ("nav_usd_robot.yaml", WHEELS), ("arm_usd.yaml", None)])
def test_an_exported_robot_reads_back_as_the_same_robot(tmp_path, scenario, wheels):
    original = _loaded(scenario)
    out = tmp_path / "robot.usda"
    assert write_robot_usd(original, out) == []  # nothing of these robots is left out
    back = load_usd(out, UrdfOptions(wheels=wheels))
    a, b = original.model, back.model
    assert (b.base_link, b.mobile, b.footprint_radius, b.drive, b.actuated, b.sensors) == \
        (a.base_link, a.mobile, a.footprint_radius, a.drive, a.actuated, a.sensors)
    fixed_by_scenario = not a.mobile and "world" not in {k.name for k in a.links}
    extra = [("root_joint", "fixed", "world", a.base_link)] if fixed_by_scenario else []
    assert _joints(b) == extra + _joints(a)  # the same names, in the same order
    assert [k.name for k in b.links] == (["world"] if extra else []) + [k.name for k in a.links]
    m1, m2 = original.spec.copy().compile(), back.spec.copy().compile()
    for field in COMPARED:
        np.testing.assert_allclose(getattr(m2, field), getattr(m1, field), rtol=2e-7,
                                   atol=1e-9, err_msg=field)
    for field in SIGNLESS:
        q1, q2 = getattr(m1, field), getattr(m2, field)
        signs = np.where((q1 * q2).sum(axis=1, keepdims=True) < 0, -1.0, 1.0)
        np.testing.assert_allclose(q2 * signs, q1, rtol=2e-7, atol=1e-7, err_msg=field)
    np.testing.assert_allclose(_geom_axes(m2), _geom_axes(m1), atol=1e-7, err_msg="geom axes")


def _geom_axes(model) -> np.ndarray:
    """Each geom's orientation as far as its shape tells it: a sphere's none; a cylinder's
    or capsule's own axis; a box's or mesh's (a mesh in its principal frame) three axes, or
    the one whose size differs where the other two are equal (a turn about it is the same
    shape), each axis up to its sign."""
    out = []
    for g in range(model.ngeom):
        r = np.zeros(9)
        mujoco.mju_quat2Mat(r, model.geom_quat[g])
        r = r.reshape(3, 3)
        size, kind = model.geom_size[g], model.geom_type[g]
        if kind == mujoco.mjtGeom.mjGEOM_SPHERE:
            keep = []
        elif kind in (mujoco.mjtGeom.mjGEOM_CYLINDER, mujoco.mjtGeom.mjGEOM_CAPSULE):
            keep = [2]
        else:
            same = [(i, j) for i in range(3) for j in range(i + 1, 3)
                    if abs(size[i] - size[j]) <= 1e-9 * max(size)]
            keep = [] if len(same) == 3 else [3 - sum(same[0])] if same else [0, 1, 2]
        axes = np.zeros((3, 3))
        for i in keep:
            axis = r[:, i]
            axes[:, i] = axis if axis[np.argmax(np.abs(axis))] > 0 else -axis
        out.append(axes)
    return np.array(out)


def test_a_world_rooted_arm_keeps_its_world_joint_and_converted_meshes_their_colours(tmp_path):
    """A description that fixes itself to a ``world`` link keeps that joint's name (no
    root_joint); ASCII STL and COLLADA meshes (one geom per colour) come back as they ran."""
    from descriptions.urdf import load_urdf

    robots = ROOT / "tests" / "robots"
    arm = load_urdf(robots / "worldarm_description" / "urdf" / "worldarm.urdf.xacro",
                    UrdfOptions(env={}, args={"base_height": "0.05"}))
    write_robot_usd(arm, tmp_path / "worldarm.usda")
    back = load_usd(tmp_path / "worldarm.usda").model
    assert _joints(back) == _joints(arm.model) and back.actuated == arm.model.actuated
    meshbot = load_urdf(robots / "meshbot_description" / "urdf" / "meshbot.urdf", UrdfOptions(
        packages={"meshbot_description": str(robots / "meshbot_description")}, env={}))
    write_robot_usd(meshbot, tmp_path / "meshbot.usda")
    m1 = meshbot.spec.copy().compile()
    m2 = load_usd(tmp_path / "meshbot.usda").spec.copy().compile()

    def meshes(m):
        return sorted((m.geom(g).name, m.mesh_vertnum[m.geom_dataid[g]],
                       tuple(np.round(m.mat_rgba[m.geom_matid[g]] if m.geom_matid[g] >= 0
                                      else m.geom_rgba[g], 6)))
                      for g in range(m.ngeom) if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH)

    assert len(meshes(m1)) == 5 and meshes(m2) == meshes(m1)  # 4 meshes, one used twice


def test_the_export_is_in_isaac_sims_importer_layout(tmp_path):
    """Prim for prim, the layout tools/make_usd_robots.py writes as Isaac's importer does:
    links as rigid bodies under the robot prim, joints with body0/body1 in a joints scope,
    drives per degree, the articulation root, root_joint for a fixed base."""
    from pxr import Usd, UsdPhysics

    def physics(path):
        stage = Usd.Stage.Open(str(path))
        out = {}
        for prim in stage.Traverse():
            if prim.HasAPI(UsdPhysics.RigidBodyAPI) or prim.IsA(UsdPhysics.Joint):
                out[str(prim.GetPath())] = (
                    prim.GetTypeName(),
                    sorted(s for s in prim.GetAppliedSchemas() if s != "NewtonJointAPI"),
                    [[str(t) for t in prim.GetRelationship(r).GetTargets()]
                     for r in ("physics:body0", "physics:body1") if prim.GetRelationship(r)])
        return stage, out

    for scenario, robot in (("nav_urdf.yaml", "mybot"), ("arm_urdf.yaml", "myarm")):
        write_robot_usd(_loaded(scenario), tmp_path / f"{robot}.usda")
        stage, exported = physics(tmp_path / f"{robot}.usda")
        _, isaac = physics(USD / f"{robot}_isaac.usda")
        assert exported == isaac
    assert stage.GetPrimAtPath("/myarm").HasAPI(UsdPhysics.ArticulationRootAPI)
    elbow = UsdPhysics.RevoluteJoint(stage.GetPrimAtPath("/myarm/joints/elbow"))
    assert elbow.GetUpperLimitAttr().Get() == pytest.approx(np.degrees(2.6))
    drive = UsdPhysics.DriveAPI(elbow.GetPrim(), "angular")
    assert drive.GetStiffnessAttr().Get() == pytest.approx(200 * np.pi / 180)  # per degree
    assert drive.GetDampingAttr().Get() == pytest.approx(20 * np.pi / 180)
    assert drive.GetMaxForceAttr().Get() == pytest.approx(40)
    mass = UsdPhysics.MassAPI(stage.GetPrimAtPath("/myarm/upper_arm_link"))
    assert mass.GetMassAttr().Get() == pytest.approx(1.5)


def _rerun(tmp_path, scenario: str, exported, usd: dict | None):
    """``scenario`` with the exported robot as its description."""
    doc = yaml.safe_load((SCENARIOS / scenario).read_text())
    doc["robots"].pop("urdf")
    doc["robots"]["description"] = str(exported)
    if usd is not None:
        doc["robots"]["usd"] = usd
    doc["world"] = str(SCENARIOS / doc["world"])
    path = tmp_path / f"exported_{scenario}"
    path.write_text(yaml.safe_dump(doc))
    return run(path, in_process=True, out=tmp_path, duration="2s", picture=False)


def _positions(done, topic: str) -> np.ndarray:
    return np.array([list(m.position) for _, m in done.messages(topic)])


def _odometry(done, topic: str) -> np.ndarray:
    return np.array([[m.pose.pose.position.x, m.pose.pose.position.y, m.pose.pose.orientation.z]
                     for _, m in done.messages(topic)])


@pytest.mark.parametrize("scenario, robot, usd", [
    ("nav_urdf.yaml", "mybot", {"wheels": list(WHEELS)}),  # lidar, IMU: the kept Gazebo tags
    ("arm_urdf.yaml", "myarm", None)])  # the drives are its position servos
def test_export_usd_of_a_urdf_robot_runs_again_as_the_same_robot(tmp_path, scenario, robot,
                                                                  usd):
    first = run(SCENARIOS / scenario, in_process=True, out=tmp_path, duration="2s",
                options=RunOptions(export_usd=True), picture=False)
    exported = first.run_dir / "robots" / f"{robot}.usda"
    assert (first.run_dir / "run.usda").is_file() and exported.is_file()
    again = _rerun(tmp_path, scenario, exported, usd)
    assert again.ticks == first.ticks == 101
    # a lone robot: its topics at the root
    assert again.last("/joint_states").name == first.last("/joint_states").name
    joints = _positions(first, "/joint_states")
    assert np.abs(joints[-1] - joints[0]).max() > 0.5  # it moved
    assert np.abs(_positions(again, "/joint_states") - joints).max() < TOLERANCE
    if robot == "mybot":
        odom = _odometry(first, "/odom")
        assert np.linalg.norm(odom[-1, :2] - odom[0, :2]) > 0.5
        assert np.abs(_odometry(again, "/odom") - odom).max() < TOLERANCE
        _plays_back_in_run_usda(first)


def _plays_back_in_run_usda(done) -> None:
    """run.usda holds the robot as its asset at /World/mybot (not MuJoCo's writer's bodies),
    each link at its recorded pose per tick."""
    from pxr import Usd, UsdGeom, UsdPhysics

    from orchestrator.outputs.usd_export import world_states

    stage = Usd.Stage.Open(str(done.run_dir / "run.usda"))
    assert stage.GetPrimAtPath("/World/Obstacles") or stage.GetPrimAtPath("/World/pillar_a")
    assert not stage.GetPrimAtPath("/World/mybot_base_footprint")
    base = stage.GetPrimAtPath("/World/mybot/base_footprint")
    assert base.HasAPI(UsdPhysics.RigidBodyAPI) and base.HasAPI(UsdPhysics.ArticulationRootAPI)
    assert stage.GetPrimAtPath("/World/mybot/joints/wheel_left_joint").HasAPI(
        UsdPhysics.DriveAPI, "angular")
    model = swarm_model(done.scenario.world, done.scenario.robots)
    free = model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT,
                                               "mybot/base_footprint_free")]
    states = dict(world_states(done.run_dir / "bag", done.scenario.tick_ns, model.nq))
    for k in (0, 100):
        where = UsdGeom.Xformable(base).ComputeLocalToWorldTransform(Usd.TimeCode(k))
        np.testing.assert_allclose(where.ExtractTranslation(), states[k][free:free + 3],
                                   atol=1e-9)
    assert not np.allclose(states[0][free:free + 2], states[100][free:free + 2])


def test_a_swarm_exports_one_robot_file_and_every_robot_in_run_usda(tmp_path):
    from pxr import Usd, UsdGeom

    done = run(SCENARIOS / "swarm_urdf.yaml", in_process=True, out=tmp_path, duration="0.1s",
               options=RunOptions(export_usd=True), check=False,
               overrides={"robots.count": 2}, picture=False)
    assert sorted(p.name for p in (done.run_dir / "robots").iterdir()) == ["mybot.usda"]
    stage = Usd.Stage.Open(str(done.run_dir / "run.usda"))
    bases = [UsdGeom.Xformable(stage.GetPrimAtPath(f"/World/bot_{i}/base_footprint"))
             for i in range(2)]
    starts = [b.ComputeLocalToWorldTransform(0).ExtractTranslation() for b in bases]
    for robot, start in zip(done.scenario.robots.robots, starts, strict=True):
        assert (start[0], start[1]) == pytest.approx(robot.start[:2], abs=1e-6)
