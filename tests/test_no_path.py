"""When no way leads to the goal: the controller says why (a note in its log, the manifest and
the summary, naming the obstacles), and the scenario warns when it loads (exit 2 with
--strict)."""

from __future__ import annotations

import json
import math

import mujoco
import numpy as np
import pytest

from descriptions.load import load_scenario
from nodes.contract import NodeConfig, Tick
from nodes.control.diagnose import explain_no_path
from nodes.control.global_planner import Planner
from nodes.control.node import ControlNode
from orchestrator.api import RunOptions, ScenarioError, ScenarioWarning, run
from tests.helpers import ROOT, orchestrate
from tests.test_control import empty_scan, odom
from tests.worlds import write_world

NAV = ROOT / "scenarios" / "nav.yaml"  # start (-3, -3), goal (3, 3)
ARENA = "".join(f'<geom name="wall_{n}" type="box" pos="{x} {y} 0.5" size="{sx} {sy} 0.5"/>'
                for n, x, y, sx, sy in (("n", 0, 4.05, 4.1, 0.05), ("s", 0, -4.05, 4.1, 0.05),
                                        ("e", 4.05, 0, 0.05, 4.1), ("w", -4.05, 0, 0.05, 4.1)))
# A pen round the goal (3, 3), open to the east where 0.2 m is left to the arena's wall.
PEN = ('<geom name="pen_n" type="box" pos="3 3.7 0.5" size="0.8 0.05 0.5"/>'
       '<geom name="pen_s" type="box" pos="3 2.3 0.5" size="0.8 0.05 0.5"/>'
       '<geom name="pen_w" type="box" pos="2.25 3 0.5" size="0.05 0.75 0.5"/>'
       '<geom name="far_box" type="box" pos="-2 1 0.4" size="0.3 0.3 0.4"/>')
CLOSERS = ["'wall_e'", "'pen_n'", "'pen_s'", "'pen_w'"]


def planner(world) -> Planner:
    return Planner(mujoco.MjModel.from_xml_path(str(world)), ControlNode.Params())


def closing(text: str) -> list[str]:
    return text.split("closing the way: obstacles ")[1].rstrip(".").split(", ")


def test_a_closed_pen_is_explained_by_the_obstacles_that_close_it(tmp_path):
    plan = planner(write_world(tmp_path, ARENA + PEN))
    assert plan.plan((-3.0, -3.0), (3.0, 3.0)) is None
    why = explain_no_path(plan, (-3.0, -3.0), (3.0, 3.0))
    assert "no passage wider than the robot (0.54 m" in why
    assert closing(why) == CLOSERS  # the walls round the goal, not the box far away
    assert plan.plan((-3.0, -3.0), (3.0, 1.5)) is not None


def test_a_start_in_an_inflated_zone_names_the_obstacles(tmp_path):
    slot = ('<geom name="left" type="box" pos="0 0.4 0.5" size="1.5 0.15 0.5"/>'
            '<geom name="right" type="box" pos="0 -0.4 0.5" size="1.5 0.15 0.5"/>')
    plan = planner(write_world(tmp_path, ARENA + slot))
    assert plan.plan((0.0, 0.0), (3.0, 3.0)) is None
    why = explain_no_path(plan, (0.0, 0.0), (3.0, 3.0))
    assert why.startswith("no path: the start (0.00, 0.00) is inside the inflated zone of "
                          "obstacles 'left', 'right' (the plan keeps 0.27 m from obstacles")


def test_a_way_closed_by_what_the_scan_saw_says_so(tmp_path):
    mid = '<geom name="mid" type="box" pos="-0.5 0 0.5" size="3.5 0.05 0.5"/>'  # 1 m gap east
    plan = planner(write_world(tmp_path, ARENA + mid))
    assert plan.plan((0.0, -2.0), (0.0, 2.0)) is not None
    plan.mark(np.column_stack([np.arange(3.0, 4.0, 0.02), np.zeros(50)]))  # across the gap
    assert plan.plan((0.0, -2.0), (0.0, 2.0)) is None
    why = explain_no_path(plan, (0.0, -2.0), (0.0, 2.0))
    assert why.endswith("closing the way: obstacles 'wall_e', 'wall_w', 'mid', points the "
                        "scan saw (marked on the map by a recovery)."), why


def test_the_node_notes_why_once_and_stands_still(tmp_path):
    node = ControlNode()
    node.reset(0, NodeConfig("control", ControlNode.Params(), 100_000_000, 100_000_000,
                             write_world(tmp_path, ARENA + PEN),
                             goal={"x": 3.0, "y": 3.0, "yaw": 0.0}))
    notes = []
    for k in range(25):  # 2.5 s: the plan is tried again after 2 s, the reason is the same
        out = node.step(Tick(k, k * 100_000_000), {"/odom": odom(-3.0, -3.0, 0.0),
                                                   "/scan": empty_scan()})
        assert out["/cmd_vel"].linear.x == 0.0 and out["/cmd_vel"].angular.z == 0.0
        assert len(out["/plan"].poses) == 0
        notes += node.take_notes()
    assert len(notes) == 1 and closing(notes[0].split(" Standing still")[0]) == CLOSERS
    assert notes[0].endswith("Standing still; trying again every 2 s.")


@pytest.fixture
def pen_nav(tmp_path) -> dict:
    """Overrides that put nav in the pen world, for 3 s."""
    return {"world": str(write_world(tmp_path, ARENA + PEN)), "duration": "3s"}


def test_the_scenario_warns_at_load_naming_the_obstacles(pen_nav):
    scenario = load_scenario(NAV, pen_nav)
    assert len(scenario.warnings) == 1
    warning = scenario.warnings[0]
    assert warning.startswith(f"{NAV}: goal: the controller's map has no way to the goal")
    assert closing(warning.split(". (world")[0]) == CLOSERS
    assert "Accepted: a goal the robot can reach" in warning
    assert load_scenario(NAV).warnings == []


def test_in_process_run_notes_and_warns_and_strict_refuses(pen_nav, tmp_path):
    with pytest.warns(ScenarioWarning, match="no way to the goal"):
        result = run(NAV, in_process=True, out=tmp_path / "runs", overrides=pen_nav, picture=False)
    assert result.status == "goal_not_met"
    [note] = result.notes
    assert (note.node, note.tick) == ("control", 0) and "closing the way" in note.text
    assert result.manifest["notes"] == [note.as_dict()]
    log = (result.run_dir / "logs" / "orchestrator.log").read_text()
    assert "note: control at tick 0 (0.000 s): no path from (-3.00, -3.00)" in log
    with pytest.raises(ScenarioError, match="refused by --strict") as refused:
        run(NAV, in_process=True, out=tmp_path / "strict", overrides=pen_nav,
            options=RunOptions(strict=True), picture=False)
    assert refused.value.key == "goal" and not (tmp_path / "strict").exists()


def test_cli_strict_exits_2_and_writes_nothing(pen_nav, tmp_path):
    args = [a for key, value in pen_nav.items() for a in ("--set", f"{key}={value}")]
    done = orchestrate(NAV, tmp_path / "runs", *args, "--strict")
    assert done.code == 2, done.stderr
    assert "goal: the controller's map has no way to the goal" in done.stderr
    assert "refused by --strict" in done.stderr
    assert not (tmp_path / "runs").exists()


def test_multi_process_run_notes_in_log_manifest_and_summary(pen_nav, tmp_path):
    args = [a for key, value in pen_nav.items() for a in ("--set", f"{key}={value}")]
    done = orchestrate(NAV, tmp_path / "runs", *args, "--set", "duration=1s")
    assert done.code == 1, done.stderr
    assert "warning: " in done.stderr and "no way to the goal" in done.stderr
    notes = done.manifest["notes"]
    assert [(n["node"], n["tick"]) for n in notes] == [("control", 0)]
    assert math.isclose(notes[0]["time_s"], 0.0) and "'pen_w'" in notes[0]["text"]
    assert "note: control at tick 0" in (done.run_dir / "logs" / "control.log").read_text()
    lines = (done.run_dir / "logs" / "control.notes.jsonl").read_text().splitlines()
    assert [json.loads(line) for line in lines] == notes
    assert "note" in done.stdout and "control at 0.00 s: no path from" in done.stdout
