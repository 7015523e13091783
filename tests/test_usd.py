"""USD worlds in (MuJoCo's importer via descriptions.worldfile), runs out as USD (--export-usd)."""

from __future__ import annotations

import shutil
from pathlib import Path

import mujoco
import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from std_msgs.msg import Float64MultiArray

from descriptions.load import load_scenario
from descriptions.worldfile import WorldError, load_world_model
from nodes.contract import NodeConfig, Tick
from nodes.physics.node import PhysicsNode
from nodes.sensors.node import SensorsNode
from orchestrator.lockstep.inprocess import run_in_process
from orchestrator.outputs.usd_export import world_states
from plan.errors import ScenarioError
from tests.helpers import ROOT, orchestrate

pxr = pytest.importorskip("pxr")
from pxr import Gf, Usd, UsdGeom  # noqa: E402

TICK = 20_000_000
WORLDS = ROOT / "scenarios" / "worlds"
NAV_XML, NAV_USD = WORLDS / "nav.xml", WORLDS / "nav.usda"


def names(model: mujoco.MjModel, kind: mujoco.mjtObj, count: int) -> list[str]:
    """Every name of one kind of element, in id order."""
    return [mujoco.mj_id2name(model, kind, i) or "" for i in range(count)]


def scan(world: Path, x: float, y: float, yaw: float) -> np.ndarray:
    """The sensors node's noiseless 360-beam scan of a world from a robot pose."""
    physics = PhysicsNode()
    physics.reset(0, NodeConfig("physics", PhysicsNode.Params(start={"x": x, "y": y, "yaw": yaw}),
                                TICK, TICK, world))
    state = physics.step(Tick(0, 0), {})["/cosim/world_state"]
    state = deserialize_message(serialize_message(state), Float64MultiArray)
    node = SensorsNode()
    params = SensorsNode.Params(lidar={"beams": 360, "range_max": 12.0, "noise_stddev": 0.0})
    node.reset(0, NodeConfig("lidar", params, TICK, 5 * TICK, world))
    msg = node.step(Tick(0, 0), {"/cosim/world_state": state})["/scan"]
    return np.frombuffer(msg.ranges, dtype=np.float32)


def write_stage(tmp_path: Path, body: str, meters_per_unit: float = 1.0, up: str = "Z") -> Path:
    """A .usda in the Isaac layout around ``body`` (prims under /World), robot.xml beside it."""
    shutil.copy(WORLDS / "robot.xml", tmp_path / "robot.xml")
    path = tmp_path / "world.usda"
    path.write_text(f'#usda 1.0\n(\n    defaultPrim = "World"\n    metersPerUnit = '
                    f'{meters_per_unit}\n    upAxis = "{up}"\n)\n\ndef Xform "World"\n{{\n'
                    f"{body}\n}}\n")
    return path


ROBOT = '''    def Xform "Robot"
    {
        custom asset cosim:robot:mjcf = @robot.xml@
        double3 xformOp:translate = (%s)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }'''


def collider(kind: str, name: str, extra: str, translate: str) -> str:
    """A static collider prim under /World/Obstacles."""
    return (f'    def {kind} "{name}" (\n        prepend apiSchemas = ["PhysicsCollisionAPI"]\n'
            f'    )\n    {{\n        {extra}\n        double3 xformOp:translate = ({translate})\n'
            '        uniform token[] xformOpOrder = ["xformOp:translate"]\n    }')


# --- loading -------------------------------------------------------------------------------

def test_usd_nav_world_has_the_mjcf_worlds_bodies_joints_and_qpos_order():
    usd, xml = load_world_model(NAV_USD), load_world_model(NAV_XML)
    assert (usd.nq, usd.nv, usd.nu, usd.nbody) == (xml.nq, xml.nv, xml.nu, xml.nbody)
    for kind, count in [(mujoco.mjtObj.mjOBJ_BODY, "nbody"), (mujoco.mjtObj.mjOBJ_JOINT, "njnt"),
                        (mujoco.mjtObj.mjOBJ_ACTUATOR, "nu"), (mujoco.mjtObj.mjOBJ_SITE, "nsite"),
                        (mujoco.mjtObj.mjOBJ_CAMERA, "ncam")]:
        assert names(usd, kind, getattr(usd, count)) == names(xml, kind, getattr(xml, count))
    np.testing.assert_allclose(usd.jnt_range, xml.jnt_range)  # robot.xml's degrees survive
    assert usd.opt.timestep == xml.opt.timestep and usd.opt.integrator == xml.opt.integrator
    assert usd.nlight == 1 and usd.geom("/World/Obstacles/Cube_01").group == 0


def test_usd_and_mjcf_nav_worlds_give_the_same_lidar_scan():
    for pose in [(-3.0, -3.0, 0.785), (1.0, 2.0, -2.0), (2.5, -2.5, 3.0)]:
        a, b = scan(NAV_XML, *pose), scan(NAV_USD, *pose)
        assert np.isfinite(a).sum() > 300
        np.testing.assert_allclose(a, b, atol=1e-5)


def test_centimetre_and_y_up_stages_load_in_metres_with_z_up(tmp_path):
    """1 m box 2 m ahead of the robot, authored in cm and Y-up: same as in metres, Z-up."""
    (tmp_path / "m").mkdir()
    (tmp_path / "cm").mkdir()
    metres = write_stage(tmp_path / "m", collider("Cube", "Box", "double size = 1",
                                                  "2.5, 0, 0.5") + "\n" + ROBOT % "0, 0, 0")
    cm_y = write_stage(tmp_path / "cm", collider("Cube", "Box", "double size = 100",
                                                 "250, 50, 0") + "\n" + ROBOT % "0, 0, 0",
                       meters_per_unit=0.01, up="Y")
    a, b = load_world_model(metres), load_world_model(cm_y)
    np.testing.assert_allclose(b.opt.gravity, [0, 0, -9.81], atol=1e-4)
    data = mujoco.MjData(b)
    mujoco.mj_forward(b, data)
    box = b.geom("/World/Box").id
    np.testing.assert_allclose(data.geom_xpos[box], [2.5, 0, 0.5], atol=1e-6)
    np.testing.assert_allclose(b.geom_size[box], a.geom_size[a.geom("/World/Box").id], atol=1e-6)
    np.testing.assert_allclose(scan(metres, 0, 0, 0), scan(cm_y, 0, 0, 0), atol=1e-5)


def test_robot_is_attached_at_its_prims_pose(tmp_path):
    world = write_stage(tmp_path, ROBOT % "1, -2, 0")
    model = load_world_model(world)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(data.xpos[model.body("base_link").id], [1, -2, 0.06], atol=1e-9)


# --- refusals --------------------------------------------------------------------------------

@pytest.mark.parametrize("body, prim, words", [
    (collider("Cone", "C", "double radius = 0.2", "0, 0, 0"), "/World/C", "Cone"),
    ('    def Xform "X" (\n        prepend apiSchemas = ["PhysicsCollisionAPI"]\n    )\n'
     '    {\n    }', "/World/X", "Xform"),
    (collider("Plane", "P", 'uniform token axis = "Y"', "0, 0, 0"), "/World/P", "axis"),
    (collider("Cube", "B", "double size = -1", "0, 0, 0"), "/World/B", "positive"),
    ('    def Sphere "S" (\n        prepend apiSchemas = ["PhysicsRigidBodyAPI", '
     '"PhysicsCollisionAPI"]\n    )\n    {\n    }\n    def PhysicsSphericalJoint "J"\n    {\n'
     '        rel physics:body1 = </World/S>\n    }', "/World/J", "PhysicsSphericalJoint"),
    ('    def Xform "Robot"\n    {\n        custom asset cosim:robot:mjcf = @nope.xml@\n    }',
     "/World/Robot", "does not resolve"),
])
def test_unloadable_prims_are_refused_naming_file_prim_and_reason(tmp_path, body, prim, words):
    world = write_stage(tmp_path, body)
    with pytest.raises(WorldError) as err:
        load_world_model(world)
    assert err.value.prim == prim and words in err.value.reason
    assert str(world) in str(err.value)


def test_usd_syntax_error_names_line(tmp_path):
    world = write_stage(tmp_path, '    def Cube "B" { double size = 1 }')
    with pytest.raises(WorldError, match=r"world\.usda:\d+:\d+"):
        load_world_model(world)


def scenario_with(tmp_path: Path, world: Path) -> Path:
    """nav_usd.yaml pointed at another world."""
    text = (ROOT / "scenarios" / "nav_usd.yaml").read_text()
    path = tmp_path / "s.yaml"
    path.write_text(text.replace("worlds/nav.usda", str(world)))
    return path


def test_broken_worlds_are_scenario_errors_before_anything_starts(tmp_path):
    cone = write_stage(tmp_path, collider("Cone", "C", "double radius = 0.2", "0, 0, 0"))
    with pytest.raises(ScenarioError) as err:
        load_scenario(scenario_with(tmp_path, cone))
    assert err.value.key == "world" and "/World/C" in str(err.value)
    broken = tmp_path / "broken.xml"
    broken.write_text("<mujoco><worldbody><geom type='box'/></worldbody>")
    with pytest.raises(ScenarioError, match="MJCF does not load"):
        load_scenario(scenario_with(tmp_path, broken))


def test_cli_refuses_a_broken_usd_world_with_exit_code_2(tmp_path):
    cone = write_stage(tmp_path, collider("Cone", "C", "double radius = 0.2", "0, 0, 0"))
    run = orchestrate(scenario_with(tmp_path, cone), tmp_path / "runs", "--in-process")
    assert run.code == 2 and run.run_dir is None
    assert "prim /World/C" in run.stderr and str(cone) in run.stderr


# --- runs ------------------------------------------------------------------------------------

def test_nav_usd_reaches_its_goal_like_nav():
    result = run_in_process(load_scenario(ROOT / "scenarios" / "nav_usd.yaml"))
    assert result.metrics["control"]["goal_reached"] == 1
    assert result.metrics["physics"]["collisions"] == 0


def test_export_usd_plays_back_the_recorded_robot_pose(tmp_path):
    run = orchestrate(ROOT / "scenarios" / "nav_usd.yaml", tmp_path, "--in-process",
                      "--export-usd", "--duration", "4s")
    assert run.code in (0, 1), run.stderr
    stage = Usd.Stage.Open(str(run.run_dir / "run.usda"))
    assert stage.GetTimeCodesPerSecond() == 1e9 / TICK
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1 and UsdGeom.GetStageUpAxis(stage) == "Z"
    assert stage.GetPrimAtPath("/World/Obstacles/Cube_01")
    base = UsdGeom.Xformable(stage.GetPrimAtPath("/World/base_link"))
    states = dict(world_states(run.run_dir / "bag", TICK, load_world_model(NAV_USD).nq))
    assert stage.GetEndTimeCode() == max(states) == len(states) - 1 == 200  # ticks 0..200
    for k in [0, 1, 57, 120, 200]:
        matrix = base.ComputeLocalToWorldTransform(Usd.TimeCode(k))
        np.testing.assert_allclose(matrix.ExtractTranslation(), states[k][:3], atol=1e-6)
        quat = Gf.Transform(matrix).GetRotation().GetQuat()
        got = np.array([quat.GetReal(), *quat.GetImaginary()])
        assert abs(abs(got @ states[k][3:7]) - 1) < 1e-6
    assert not np.allclose(states[0][:2], states[200][:2])  # it moved


def test_export_usd_of_an_mjcf_world(tmp_path):
    run = orchestrate(ROOT / "scenarios" / "nav.yaml", tmp_path, "--in-process",
                      "--export-usd", "--duration", "1s")
    stage = Usd.Stage.Open(str(run.run_dir / "run.usda"))
    assert stage.GetPrimAtPath("/World/base_link") and stage.GetEndTimeCode() == 50
    geoms = [p for p in stage.Traverse() if p.GetName() == "blocker"]
    assert geoms, "the MJCF world's static geoms are written too"
