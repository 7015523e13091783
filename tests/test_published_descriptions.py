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
    from descriptions.urdf_state import UrdfFrames

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
    frames = UrdfFrames(model, robot.scoped("ur"))
    fixed = {(t.parent, t.child): t for t in frames.static(data)}
    world = fixed[("ur/world", "ur/base_link")]
    assert world.pos == pytest.approx((0, 0, 0.05)) and world.quat == pytest.approx((1, 0, 0, 0))
    assert ("ur/forearm_link", "ur/tool0") in fixed
    with pytest.raises(DescriptionError, match="root link is 'world'"):
        load_urdf(WORLDARM, UrdfOptions(env={}, base="free"))


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
    states = bag_messages(inproc.run_dir, "/ur/joint_states")[-1]
    assert list(states.name) == ARM_JOINTS
    assert list(states.position) == pytest.approx([0.3, -0.3, 0.5], abs=0.05)
    static = {(t.header.frame_id, t.child_frame_id): t.transform.translation
              for t in bag_messages(inproc.run_dir, "/tf_static")[0].transforms}
    assert static[("ur/world", "ur/base_link")].z == pytest.approx(0.02)
    moving = {(t.header.frame_id, t.child_frame_id)
              for t in bag_messages(inproc.run_dir, "/tf")[-1].transforms}
    assert ("ur/base_link", "ur/shoulder_link") in moving
