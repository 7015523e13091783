"""What enters a run from outside enters at a tick boundary and is recorded: the scenario's
external node publishes the latest arrival of each topic; the same arrivals at the same
ticks give the same digest multi-process and in-process, and the bag has them."""

from __future__ import annotations

import threading

import pytest
import yaml
from geometry_msgs.msg import PoseStamped

from orchestrator import api
from orchestrator.api import Arrivals, ScenarioError, load, run
from tests.helpers import ROOT

NAV = ROOT / "scenarios" / "nav.yaml"


def nav_with_goal_input(tmp_path, duration="4s"):
    """nav (no camera) whose control node also takes /goal_pose from outside."""
    doc = yaml.safe_load(NAV.read_text())
    doc["duration"] = duration
    doc["world"] = str((NAV.parent / doc["world"]).resolve())
    doc["nodes"] = [n for n in doc["nodes"] if n["name"] != "camera"]
    doc["external"] = {"rate": 10, "topics": {"/goal_pose": "geometry_msgs/msg/PoseStamped"}}
    control = next(n for n in doc["nodes"] if n["name"] == "control")
    control["inputs"].append({"topic": "/goal_pose", "mode": "same_tick"})
    path = tmp_path / "nav_goal.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def goal(x: float, y: float) -> PoseStamped:
    msg = PoseStamped()
    msg.header.frame_id = "odom"
    msg.pose.position.x, msg.pose.position.y = x, y
    msg.pose.orientation.w = 1.0
    return msg


def replay(tick: int) -> dict:
    return {"/goal_pose": goal(-3.0, 0.5)} if tick == 50 else {}


def test_the_same_arrivals_give_one_digest_multi_and_in_process(tmp_path):
    path = nav_with_goal_input(tmp_path)
    multi = run(path, out=tmp_path / "m", external=replay, check=True, picture=False)
    inproc = run(path, in_process=True, out=tmp_path / "i", external=replay, picture=False)
    plain = run(path, in_process=True, out=tmp_path / "p", picture=False)
    assert multi.digest == inproc.digest != plain.digest
    goals = [(stamp, msg.header.frame_id, msg.pose.position.x)
             for stamp, msg in multi.messages("/goal_pose")]
    assert len(goals) == 41  # the external node at 10 Hz over 4 s, tick 0 included
    assert all(frame == "" for stamp, frame, _ in goals if stamp < 1_000_000_000)
    assert all((frame, x) == ("odom", -3.0) for stamp, frame, x in goals
               if stamp >= 1_000_000_000)
    # the new goal turned the robot around: its plan ends at the new goal from tick 50 on
    last_plan = multi.last("/plan")
    assert last_plan.poses[-1].pose.position.x == pytest.approx(-3.0)


class SentMidRun(Arrivals):
    """Arrivals into which a client thread puts a goal while the run is at tick ``at`` (or
    the first external tick after it): the external node's take there waits for the client,
    as a run paused by a client waits for its step, so ticks 0 .. at-1 have run when the goal
    comes and it enters at that tick however loaded the machine is."""

    def __init__(self, topics: dict, at: int):
        super().__init__(topics)
        self.at = at
        self.reached = threading.Event()  # the run is at tick ``at``: the client may send
        self.sent = threading.Event()
        self.reached_tick: int | None = None

    def take(self, tick: int | None = None) -> dict:
        """What arrived since the last take; at the chosen tick, after the client sent."""
        if tick is not None and tick >= self.at and not self.reached.is_set():
            self.reached_tick = tick
            self.reached.set()
            assert self.sent.wait(timeout=120), "the client never sent"  # a hang guard
        return super().take(tick)


def client(arrivals: SentMidRun) -> None:
    """A client in its own thread: waits until the run is mid-way, then sends one goal."""
    if arrivals.reached.wait(timeout=120):
        arrivals.put("/goal_pose", goal(-3.0, 0.5))
        arrivals.sent.set()


def test_live_arrivals_mid_run_enter_at_that_tick_and_replay(tmp_path):
    path = nav_with_goal_input(tmp_path, duration="2s")
    scenario = load(path)
    arrivals = SentMidRun(scenario.nodes["external"].outputs, at=scenario.schedule.last_tick // 2)
    sender = threading.Thread(target=client, args=(arrivals,), daemon=True)
    sender.start()
    live = run(scenario, out=tmp_path / "live", external=arrivals, picture=False)
    sender.join(timeout=120)
    assert arrivals.reached_tick is not None and arrivals.reached_tick > 0
    published = [(stamp // scenario.tick_ns, msg.header.frame_id)
                 for stamp, msg in live.messages("/goal_pose")]
    entered = [tick for tick, frame in published if frame]
    assert entered, "the goal never entered the run"
    assert entered[0] == arrivals.reached_tick  # the tick at which it came, not tick 0
    # nothing before it, and the external node held it from then on
    assert all(bool(frame) == (tick >= entered[0]) for tick, frame in published)

    def again(tick: int) -> dict:
        return {"/goal_pose": goal(-3.0, 0.5)} if tick == entered[0] else {}

    replayed = run(scenario, in_process=True, out=tmp_path / "again", external=again, picture=False)
    assert replayed.digest == live.digest
    # and from the run directory alone: the arrivals it recorded, as they arrived
    again_dir = api.replay(live.run_dir, in_process=True, out=tmp_path / "replay")
    assert again_dir.digest == live.digest
    period = scenario.nodes["external"].period_ticks
    earlier = run(scenario, in_process=True, out=tmp_path / "earlier",
                  external=lambda tick: again(tick + period),
                  picture=False)  # one external tick early
    assert earlier.digest != live.digest  # the tick it entered at is part of the run


def test_the_external_name_is_reserved(tmp_path):
    doc = yaml.safe_load(nav_with_goal_input(tmp_path).read_text())
    doc["nodes"][0]["name"] = "external"
    path = tmp_path / "clash.yaml"
    path.write_text(yaml.safe_dump(doc))
    with pytest.raises(ScenarioError, match="reserved"):
        load(path)


def test_arrivals_refuse_unknown_topics_and_wrong_types():
    arrivals = Arrivals({"/goal_pose": PoseStamped})
    with pytest.raises(KeyError, match="not an external topic"):
        arrivals.put("/other", PoseStamped())
    with pytest.raises(TypeError, match="takes PoseStamped"):
        arrivals.put("/goal_pose", 3)
