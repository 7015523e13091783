"""Descriptions as they are published (issue 47 item 4), on small descriptions written in
those shapes under tests/robots/: an arm whose URDF starts at a link named ``world`` (UR,
Franka). In-process except the one multi-process run the world-rooted arm's bug needed."""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import pytest

from descriptions.description_error import DescriptionError
from descriptions.urdf import UrdfOptions, load_urdf
from tests.helpers import orchestrate

ROOT = Path(__file__).resolve().parent.parent
ROBOTS = ROOT / "tests" / "robots"
WORLDARM = ROBOTS / "worldarm_description" / "urdf" / "worldarm.urdf.xacro"
WORLDARM_RUN = ROOT / "tests" / "scenarios" / "worldarm.yaml"
ARM_JOINTS = ["shoulder_pan", "shoulder_lift", "elbow"]


# -- a root link named 'world' ---------------------------------------------------------

def test_a_world_rooted_arm_is_fixed_where_it_is_placed():
    from descriptions.robot_state import RobotStateFrames

    loaded = load_urdf(WORLDARM, UrdfOptions(env={}, args={"base_height": "0.05"}))
    robot = loaded.model
    assert robot.base_link == "base_link" and not robot.mobile
    assert [a.joint for a in robot.actuated] == ARM_JOINTS
    spec = mujoco.MjSpec()
    spec.copy_during_attach = True
    frame = spec.worldbody.add_frame(pos=[1.0, 2.0, 0.0], quat=[math.cos(0.25), 0, 0,
                                                                math.sin(0.25)])
    spec.attach(loaded.spec, frame=frame, prefix="ur/")
    model = spec.compile()
    bodies = [model.body(i).name for i in range(1, model.nbody)]
    assert "ur/world" not in bodies and "ur/base_link" in bodies
    assert model.nq == 3 and model.njnt == 3  # no free joint: the base is fixed
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    base = model.body("ur/base_link").id
    assert int(model.body_parentid[base]) == 0
    assert data.xpos[base] == pytest.approx([1.0, 2.0, 0.05])  # the placement, then origin
    # TF as robot_state_publisher gives it: world -> base_link is the joint's origin
    frames = RobotStateFrames(model, robot.scoped("ur"))
    fixed = {(t.parent, t.child): t for t in frames.static(data)}
    world = fixed[("ur/world", "ur/base_link")]
    assert world.pos == pytest.approx((0, 0, 0.05)) and world.quat == pytest.approx((1, 0, 0, 0))
    assert ("ur/forearm_link", "ur/tool0") in fixed
    with pytest.raises(DescriptionError, match="root link is 'world'"):
        load_urdf(WORLDARM, UrdfOptions(env={}, base="free"))
    from descriptions.describe import account

    text = account(loaded, UrdfOptions())
    assert "base link: base_link (fixed to the world)" in text
    assert "world  [the world where the robot is placed: a site, not a body]" in text


def test_a_world_holding_two_links_is_named(tmp_path):
    inertial = ('<inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" '
                'ixy="0" ixz="0" iyz="0"/></inertial>')
    path = tmp_path / "two.urdf"
    path.write_text('<robot name="two"><link name="world"/>' + "".join(
        f'<joint name="j{i}" type="fixed"><parent link="world"/><child link="b{i}"/></joint>'
        f'<link name="b{i}">{inertial}</link>' for i in (1, 2)) + "</robot>")
    with pytest.raises(DescriptionError, match="link 'world'.*holds 2 links.*b1, b2"):
        load_urdf(path, UrdfOptions(env={}))


def test_a_world_rooted_arm_runs_with_one_digest_and_its_own_frames(tmp_path):
    from tests.test_arm import bag_messages

    inproc = orchestrate(WORLDARM_RUN, tmp_path, "--in-process", "--quiet")
    multi = orchestrate(WORLDARM_RUN, tmp_path, "--quiet")
    for run in (inproc, multi):
        assert run.code == 0, run.stderr
        assert run.manifest["outcome"]["metrics"]["ur/x"] == pytest.approx(0.5)
    assert inproc.manifest["digest"] == multi.manifest["digest"]
    states = bag_messages(inproc.run_dir, "/joint_states")[-1]  # a lone robot: the root
    assert list(states.name) == ARM_JOINTS
    assert list(states.position) == pytest.approx([0.3, -0.3, 0.5], abs=0.05)
    static = {(t.header.frame_id, t.child_frame_id): t.transform.translation
              for t in bag_messages(inproc.run_dir, "/tf_static")[0].transforms}
    assert static[("world", "base_link")].z == pytest.approx(0.02)
    moving = {(t.header.frame_id, t.child_frame_id)
              for t in bag_messages(inproc.run_dir, "/tf")[-1].transforms}
    assert ("base_link", "shoulder_link") in moving


# -- ASCII STL and COLLADA meshes ------------------------------------------------------

MESHBOT = ROBOTS / "meshbot_description" / "urdf" / "meshbot.urdf"
MESHBOT_PACKAGES = {"meshbot_description": str(ROBOTS / "meshbot_description")}
MESHBOT_RUN = ROOT / "tests" / "scenarios" / "meshbot.yaml"


def _extent(model, data, geom: int):
    from descriptions.urdf_geometry import geom_points

    pts = geom_points(model, data, geom)
    return pts.min(axis=0), pts.max(axis=0)


def test_ascii_stl_and_collada_meshes_load_as_rviz_draws_them(tmp_path, monkeypatch):
    from descriptions import mesh_convert

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    mesh_convert._converted.cache_clear()
    loaded = load_urdf(MESHBOT, UrdfOptions(packages=MESHBOT_PACKAGES, env={}))
    assert sum("converted to binary STL" in n for n in loaded.notes) == 4
    model = loaded.spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    geoms = {model.geom(g).name: g for g in range(model.ngeom)}
    assert set(geoms) == {"base_link_visual_0", "base_link_collision_0", "turret_link_visual_0",
                          "turret_link_visual_1", "turret_link_collision_0"}
    assert all(model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH for g in geoms.values())
    # the ASCII STL box, 0.2 x 0.2 x 0.1 m about base_link
    lo, hi = _extent(model, data, geoms["base_link_collision_0"])
    assert lo == pytest.approx([-0.1, -0.1, -0.05]) and hi == pytest.approx([0.1, 0.1, 0.05])
    # the COLLADA turret in millimetres, on the joint 0.05 m up: a red body 60 x 60 x 120 mm
    # and a blue 20 mm cap on it, each part its own visual with its own colour
    red, blue = geoms["turret_link_visual_0"], geoms["turret_link_visual_1"]
    # (trimesh keeps a material's colour in bytes: within 1/255)
    assert model.geom_rgba[red] == pytest.approx([0.8, 0.1, 0.1, 1.0], abs=1 / 255)
    assert model.geom_rgba[blue] == pytest.approx([0.1, 0.2, 0.9, 1.0], abs=1 / 255)
    lo, hi = _extent(model, data, red)
    assert lo == pytest.approx([-0.03, -0.03, 0.05]) and hi == pytest.approx([0.03, 0.03, 0.17])
    lo, hi = _extent(model, data, blue)
    assert lo == pytest.approx([-0.01, -0.01, 0.17]) and hi == pytest.approx([0.01, 0.01, 0.19])
    lo, hi = _extent(model, data, geoms["turret_link_collision_0"])  # both parts, one mesh
    assert lo == pytest.approx([-0.03, -0.03, 0.05]) and hi == pytest.approx([0.03, 0.03, 0.19])
    # converted once: a second load (another process) reads the cache and writes nothing
    written = {p: p.stat().st_mtime_ns for p in (tmp_path / "cosim" / "meshes").iterdir()}
    assert len([p for p in written if p.suffix == ".stl"]) == 4
    mesh_convert._converted.cache_clear()
    again = load_urdf(MESHBOT, UrdfOptions(packages=MESHBOT_PACKAGES, env={}))
    assert again.spec.to_xml() == loaded.spec.to_xml()
    assert {p: p.stat().st_mtime_ns for p in (tmp_path / "cosim" / "meshes").iterdir()} == written


def test_a_collada_file_that_does_not_read(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    (tmp_path / "m.dae").write_text("<COLLADA/>")
    inertial = ('<inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" '
                'ixy="0" ixz="0" iyz="0"/></inertial>')
    path = tmp_path / "r.urdf"
    mesh = '<geometry><mesh filename="m.dae"/></geometry>'
    path.write_text(f'<robot name="r"><link name="base">{inertial}<visual>{mesh}</visual>'
                    '<collision><geometry><box size="0.1 0.1 0.1"/></geometry></collision>'
                    '</link></robot>')
    loaded = load_urdf(path, UrdfOptions(env={}))  # a visual: drawn with the collision box
    assert any("m.dae" in n and "collision geometry" in n for n in loaded.notes)
    path.write_text(f'<robot name="r"><link name="base">{inertial}<collision>{mesh}'
                    '</collision></link></robot>')
    with pytest.raises(DescriptionError, match="link 'base'.*collision mesh 'm.dae'.*does not "
                       "read.*binary STL or OBJ"):
        load_urdf(path, UrdfOptions(env={}))


def test_the_mesh_robot_runs_and_describe_draws_its_colours(tmp_path):
    import subprocess
    import sys

    import numpy as np
    from matplotlib import image

    from orchestrator.api import run

    result = run(MESHBOT_RUN, in_process=True, out=tmp_path, picture=False)
    assert result.success, result.error
    assert list(result.last("/joint_states").position) == pytest.approx([0.8], abs=0.05)
    png = tmp_path / "meshbot.png"
    out = subprocess.run([sys.executable, "-m", "descriptions.describe", str(MESHBOT_RUN),
                          "--picture", str(png)], capture_output=True, text=True, timeout=120,
                         cwd=ROOT)
    assert out.returncode == 0, out.stderr
    assert "turret.dae' (COLLADA) converted to binary STL (2 parts" in out.stdout
    rgb = image.imread(png)[..., :3]
    red = (rgb[..., 0] > 0.6) & (rgb[..., 1] < 0.25) & (rgb[..., 2] < 0.25)
    blue = (rgb[..., 2] > 0.6) & (rgb[..., 0] < 0.25)
    assert red.sum() > 500 and blue.sum() > 50, (red.sum(), blue.sum())
    assert np.std(rgb) > 0.05
