"""Worlds that cannot work are refused when the scenario loads (exit 2, nothing started or
written): non-finite numbers, a world path that is a directory, a world without the robot,
a start or goal outside the world, inside an obstacle or too close to one."""

from __future__ import annotations

import pytest

from descriptions.load import load_scenario
from plan.errors import ScenarioError
from tests.helpers import ROOT, orchestrate
from tests.worlds import write_world

NAV = ROOT / "scenarios" / "nav.yaml"


def refused(overrides: dict) -> ScenarioError:
    with pytest.raises(ScenarioError) as info:
        load_scenario(NAV, overrides)
    return info.value


@pytest.mark.parametrize(("overrides", "key", "words"), [
    ({"goal.x": float("nan")}, "goal.x", ["nan is not a finite number", "override goal.x"]),
    ({"goal.position_tolerance": float("inf")}, "goal.position_tolerance", ["inf"]),
    ({"nodes.control.params.max_turn": "inf"}, "nodes[3] (control).params.max_turn",
     ["inf is not a finite number"]),
    ({"nodes.physics.params.start.yaw": float("nan")}, "nodes[0] (physics).params.start.yaw",
     ["nan"]),
    ({"world": "worlds"}, "world", ["is a directory"]),
    ({"goal.x": 0.0, "goal.y": 0.0}, "goal", ["inside obstacle 'blocker' (box)"]),
    ({"goal.x": 9.0}, "goal", ["outside the world", "x -4.1 to 4.1"]),
    ({"goal.x": 3.85, "goal.y": 0.0}, "goal", ["from obstacle 'wall_e'", "robot's radius"]),
    ({"nodes.physics.params.start.x": -3.9}, "nodes[0] (physics).params.start",
     ["from obstacle 'wall_w'", "closer than the robot's radius"]),
    ({"nodes.physics.params.start.x": 2.2, "nodes.physics.params.start.y": 1.0},
     "nodes[0] (physics).params.start", ["inside obstacle 'box_b'"]),
    ({"nodes.physics.params.base_body": "chassis"}, "nodes[0] (physics).params.base_body",
     ["no body 'chassis'", "base_link"]),
])
def test_impossible_worlds_are_refused_naming_the_key(overrides, key, words):
    err = refused(overrides)
    assert err.key == key, str(err)
    for word in words:
        assert word in str(err), str(err)
    assert err.accepted


def test_a_sensor_the_mjcf_robot_lacks_names_the_site_and_the_parameter():
    err = refused({"nodes.lidar.params.lidar.site": "lidar_mount"})
    problems = {e.key: e for e in err.errors}
    assert set(problems) == {"nodes[1] (lidar).params.lidar", "nodes[3] (control)"}, str(err)
    lidar = problems["nodes[1] (lidar).params.lidar"]
    assert lidar.problem.startswith("the robot has no lidar") and "'lidar_mount'" in lidar.problem
    assert "params.lidar.site" in lidar.accepted
    camera = refused({"nodes.camera.params.camera.camera": "front"})
    assert camera.key == "nodes[2] (camera).params.camera"
    assert "no camera 'front'" in camera.problem and "params.camera.camera" in camera.accepted
    # the robot is read by the control node's name; the lidar node falls back to its own
    control = refused({"nodes.control.params.laser_site": "lidar_mount"})
    assert control.key == "nodes[3] (control)" and len(control.errors) == 1, str(control)
    assert "no site 'lidar_mount'" in control.problem
    both = refused({"nodes.control.params.laser_site": "lidar_mount",
                    "nodes.lidar.params.lidar.site": "laser"})
    assert both.key == "nodes" and "name the robot's laser_site differently" in both.problem


def test_a_world_without_the_robot_is_refused(tmp_path):
    world = write_world(tmp_path, '<geom name="wall" type="box" pos="0 2 0.3" size="1 0.1 0.3"/>')
    world.write_text(world.read_text().replace('<include file="robot.xml"/>', ""))
    err = refused({"world": str(world)})
    assert err.key == "nodes[0] (physics).params.base_body"
    assert "no body 'base_link' (the robot this node drives)" in str(err)


def test_cli_exits_2_and_writes_nothing(tmp_path):
    done = orchestrate(NAV, tmp_path / "runs", "--set", "goal.x=.nan")
    assert done.code == 2 and "goal.x: nan is not a finite number" in done.stderr
    assert not (tmp_path / "runs").exists()
