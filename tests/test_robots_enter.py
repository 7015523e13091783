"""Robots that enter and leave a running simulation (issue 49): a scenario's ``events:``
bring robots in (``robot: {name, start, goal}``) and take them out (``delete:``).

Each such robot's ``for_each: robot`` nodes (its lidar and controller) are planned and
started at launch like every other node and are dormant until the tick their robot enters
(``plan.schedule``'s windows): physics attaches the robot's description at that tick
boundary (MjSpec attach and recompile, every other body's state kept bit for bit), its
topics carry samples from then on, and at its delete they go quiet and its nodes stop
being scheduled. tests/scenarios/swarm_enter.yaml: robot_0 and robot_1 (MJCF) from the
start, ``gone`` (USD) in at 0.4 s and out at 1.2 s, ``late`` (URDF, xacro) in at 1 s,
driven to its goal.
"""

from __future__ import annotations

import collections

import mujoco
import numpy as np
import pytest

from descriptions.load import load_scenario
from nodes.physics.world_events import LiveWorld
from orchestrator.api import run
from orchestrator.lockstep.inprocess import run_in_process
from plan.errors import ScenarioError
from plan.options import RunOptions
from tests.helpers import ROOT

SCENARIO = ROOT / "tests" / "scenarios" / "swarm_enter.yaml"
S = 1_000_000_000


@pytest.fixture(scope="module")
def counted():
    """The scenario over 2 s in-process: how often each node acted and each topic was
    published, and the first and last tick of each."""
    scenario = load_scenario(SCENARIO, {"duration": "2s"})
    count: collections.Counter = collections.Counter()
    ticks: dict[str, list[int]] = {}

    def observe(k: int, name: str, items) -> None:
        for key in (name, *(topic for topic, _ in items)):
            count[key] += 1
            ticks.setdefault(key, [k, k])[1] = k

    result = run_in_process(scenario, observe)
    return scenario, count, ticks, result.digest


def test_a_robots_nodes_act_only_while_it_is_in_the_world(counted):
    scenario, count, ticks, _ = counted
    # 50 Hz ticks: gone is in for ticks [20, 60), late from 50 on; their nodes run at 10 Hz
    assert scenario.schedule.windows["control@gone"] == (20, 60)
    assert scenario.schedule.windows["lidar@late"] == (50, None)
    assert ticks["control@gone"] == [20, 55] and count["control@gone"] == 8
    assert ticks["lidar@late"] == [50, 100] and count["lidar@late"] == 11
    assert ticks["control@robot_0"] == [0, 100] and count["control@robot_0"] == 21
    # physics publishes a robot's topics only while it is there
    assert ticks["/gone/odom"] == [20, 59] and count["/gone/odom"] == 40
    assert ticks["/late/odom"][0] == 50 and count["/late/odom"] == 51
    assert count["/robot_0/odom"] == count["physics"] == 101
    # the fixed frames again, whole, at each tick a robot enters (latched: the newest stays)
    assert count["/tf_static"] == 3 and ticks["/tf_static"] == [0, 50]


def test_one_digest_in_process_multi_process_and_packed_by_kind(counted, tmp_path):
    """Independent runs of the same 2 s: every node its own process, and packed by kind."""
    _, _, _, reference = counted
    separate = run(SCENARIO, out=tmp_path, duration="2s", picture=False)
    packed = run(SCENARIO, out=tmp_path, duration="2s", options=RunOptions(pack="kind"),
                 picture=False)
    assert separate.digest == packed.digest == reference


def test_the_robot_that_entered_reaches_its_goal(tmp_path):
    result = run(SCENARIO, in_process=True, out=tmp_path, duration="4s", picture=False)
    metrics = result.metrics
    assert metrics["late/arrived"] == 1.0, metrics
    assert 1.0 < metrics["late/time_to_goal"] < 4.0
    assert metrics["collisions"] == 0
    odom = [(t, o.pose.pose.position.x) for t, o in result.messages("/late/odom")]
    assert odom[0][0] == 1 * S and abs(odom[0][1] - -2.5) < 0.01  # it entered at its start
    assert [t for t, _ in result.messages("/gone/odom")][-1] < 1.2 * S  # quiet once deleted


def test_attaching_and_removing_a_robot_keeps_every_other_body_bit_for_bit():
    scenario = load_scenario(SCENARIO)
    live = LiveWorld(scenario.world, scenario.robots, tuple(scenario.model.events))
    data = mujoco.MjData(live.model)
    for _ in range(50):
        mujoco.mj_step(live.model, data)
    before = data.qpos.copy()
    model, after = live.advance(data, int(0.4 * S))  # gone enters
    assert model.nq > len(before)
    assert np.array_equal(after.qpos[:len(before)], before)  # appended after the others
    assert "gone" in live.robots
    model, after = live.advance(after, int(1.2 * S))  # late enters, gone leaves
    assert live.robots == {"robot_0", "robot_1", "late"}
    assert np.array_equal(after.qpos[:len(before)], before)


@pytest.mark.parametrize("events, key, says", [
    ("- {at: 1s, robot: {name: robot_0, start: {x: 0, y: 2}, goal: {x: 0, y: -2}}}",
     "events[0] (robot_0).robot.name", "already a robot"),
    ("- {at: 1s, robot: {name: a, start: {x: 0, y: 2}, goal: {x: 0, y: -2}}}\n"
     "  - {at: 2s, robot: {name: a, start: {x: 0, y: 2}, goal: {x: 0, y: -2}}}",
     "events[1] (a).robot.name", "still in the world"),
    ("- {at: 1s, robot: {name: a, start: {x: 0, y: 2}, goal: {x: 0, y: -2}}}\n"
     "  - {at: 2s, delete: a}\n"
     "  - {at: 3s, robot: {name: a, start: {x: 0, y: 2}, goal: {x: 0, y: -2}}}",
     "events[2] (a).robot.name", "enters once"),
    ("- {at: 15ms, robot: {name: a, start: {x: 0, y: 2}, goal: {x: 0, y: -2}}}",
     "events[0] (a).at", "not on a tick"),
    ("- {at: 1s, robot: {name: a, start: {x: 0, y: 2}, goal: {x: 0, y: -2}, "
     "description: nowhere.urdf}}", "events[0] (a).robot.description", "does not exist"),
    ("- {at: 1s, robot: {name: a, start: {x: 1.3, y: 1.3}, goal: {x: 0, y: -2}}}",
     "events[0] (a).robot.start", "pillar_a"),
    ("- {at: 1s, robot: {name: a, start: {x: 0, y: 2}, goal: {x: 0, y: -2}}}\n"
     "  - {at: 1s, robot: {name: b, start: {x: 0.1, y: 2}, goal: {x: 0, y: -2}}}",
     "events[1] (b).robot.start", "overlaps 'a'"),
    ("- {at: 1s, robot: {name: a, start: {x: 0, y: 2}, goal: {x: 0, y: -2}, "
     "description: nowhere.urdf, usd: {}}}", "events[0] (a).robot", "does not exist"),
])
def test_bad_robot_events_are_refused_naming_the_key(tmp_path, events, key, says):
    text = SCENARIO.read_text()
    head, _, rest = text.partition("events:\n")
    _, _, tail = rest.partition("success:")
    path = tmp_path / "bad.yaml"
    path.write_text(head.replace("../../scenarios/", str(ROOT / "scenarios") + "/")
                    + "events:\n  " + events + "\nsuccess:" + tail)
    with pytest.raises(ScenarioError) as err:
        load_scenario(path)
    assert key in str(err.value) and says in str(err.value), str(err.value)


def test_a_spawnable_that_does_not_exist_is_refused_naming_the_key(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text(SCENARIO.read_text().replace("../../scenarios/", str(ROOT / "scenarios")
                                                 + "/") + "spawnables: [models/, x.urdf]\n")
    (tmp_path / "x.urdf").write_text("<robot name='x'/>")
    with pytest.raises(ScenarioError) as err:
        load_scenario(path)
    assert "spawnables[0].path" in str(err.value) and "x.urdf" not in str(err.value)


def test_events_from_python_are_those_of_the_file(counted, tmp_path):
    """swarm_enter's events given through orchestrator.api to the scenario without them:
    the same run, digest for digest."""
    from orchestrator.api import delete, spawn_robot

    bare = tmp_path / "bare.yaml"
    text = SCENARIO.read_text().replace("../../scenarios/", str(ROOT / "scenarios") + "/")
    head, _, rest = text.partition("events:\n")
    bare.write_text(head + "success:" + rest.partition("success:")[2])
    robots = ROOT / "scenarios" / "robots"
    wheels = ["wheel_left_joint", "wheel_right_joint"]
    events = [spawn_robot("late", at="1s", start=(-2.5, 0.0, 0.0), goal=(-1.2, 0.0),
                          description=robots / "mybot_description/urdf/mybot.urdf.xacro",
                          urdf={"packages": {"mybot_description": robots / "mybot_description"},
                                "wheels": wheels}),
              spawn_robot("gone", at="400ms", start=(0.0, 2.5, -1.5708), goal=(0.0, -2.5),
                          description=robots / "usd/mybot_isaac.usda",
                          usd={"wheels": wheels, "sensors": {"lidar": "base_scan"}}),
              delete("gone", at="1200ms")]
    result = run(bare, in_process=True, out=tmp_path, duration="2s", events=events, picture=False)
    assert result.digest == counted[3]


def test_a_dormant_node_keeps_no_input_it_cannot_take():
    """A robot's node before its window (here a client's robot: not opened yet, then opened
    at tick 503) and after it keeps no more samples than it can take: one while it waits,
    none it would never take after it left (it used to keep every sample it never took)."""
    from std_msgs.msg import String

    from plan.schedule import DELAYED, NEVER, SAME_TICK, Edge, Schedule
    from runtime.exchange import InputHistory

    edges = [Edge("lidar", "physics", "/w", SAME_TICK), Edge("lidar", "physics", "/c", DELAYED)]
    sched = Schedule(1, 1000, {"physics": 2, "lidar": 5}, edges, {"lidar": (NEVER, None)})
    histories = []
    for edge in sched.inputs_of["lidar"]:
        histories.append(InputHistory(edge.topic, String))
        histories[-1].keep_for(sched, edge)
    held = {}
    for k in range(0, 1001, 2):
        if k == 504:  # the window opens before any node reaches it (the master's handshake)
            sched.windows["lidar"] = (503, 700)
        for history in histories:
            history.push_bytes(k, b"x")
        for j in (k, k + 1):
            if sched.is_due("lidar", j):
                for index, wanted in sched.inputs_at("lidar", j):
                    histories[index].take_raw(wanted)
        held[k] = max(len(h.samples) for h in histories)
    assert max(v for k, v in held.items() if k < 504) == 1
    assert max(v for k, v in held.items() if 504 <= k < 700) <= 4
    assert max(v for k, v in held.items() if k >= 700) <= 1


def _imu_run(tmp_path, events: str) -> dict[str, list]:
    """swarm_enter with IMUs, given ``events``, over 1 s in-process: each robot's /imu
    readings (gyro and accelerometer) by tick."""
    from sensor_msgs.msg import Imu

    from runtime.cdr.decode import decode

    text = SCENARIO.read_text().replace("../../scenarios/", str(ROOT / "scenarios") + "/")
    head, _, rest = text.partition("events:\n")
    path = tmp_path / f"imu{len(list(tmp_path.iterdir()))}.yaml"
    path.write_text(head + events + "success:" + rest.partition("success:")[2]
                    .replace("params: {imu: null}", "params: {}"))
    readings: dict[str, list] = collections.defaultdict(list)

    def observe(k: int, name: str, items) -> None:
        for topic, data in items:
            if topic.endswith("/imu"):
                msg = decode(data, Imu)
                w, a = msg.angular_velocity, msg.linear_acceleration
                readings[topic].append((k, w.x, w.y, w.z, a.x, a.y, a.z))

    run_in_process(load_scenario(path, {"duration": "1s"}), observe)
    return readings


def test_a_robot_that_enters_leaves_every_imu_bias_and_noise_as_it_was(tmp_path):
    """A robot entering (or leaving) redrew every robot's IMU bias and took noise from the
    others' generator: robot_0's and robot_1's readings are now those of a run without it,
    and the one that enters draws from a generator of its own name, the same whenever it
    enters (at rest where it enters: its first reading the same at 0.4 s or 0.6 s)."""
    late = ("events:\n  - {at: %s, robot: {name: late, start: {x: -2.5, y: 0.0}, "
            "goal: {x: -1.2, y: 0.0}}}\n  - {at: 800ms, delete: late}\n")
    without = _imu_run(tmp_path, "")
    early, later = _imu_run(tmp_path, late % "400ms"), _imu_run(tmp_path, late % "600ms")
    for robot in ("/robot_0/imu", "/robot_1/imu"):
        assert early[robot] == without[robot] == later[robot]
    assert early["/late/imu"][0][0] == 20 and later["/late/imu"][0][0] == 30
    assert early["/late/imu"][0][1:] == later["/late/imu"][0][1:]


def test_events_added_to_a_loaded_scenario_keep_its_robots_settings():
    """orchestrator.api adding an event to a loaded Scenario re-read the scenario's events
    from its checked model, which holds no urdf:/usd: settings any more: swarm_enter's
    late robot lost its packages (exit 2: package 'mybot_description' not found)."""
    from orchestrator.api import load, spawn_object

    loaded = load(SCENARIO, duration="2s")
    more = load(loaded, events=[spawn_object("crate", at="1s", shape="box",
                                             pose=(1.0, 1.0), size=(0.2, 0.2, 0.2))])
    assert [e.name for e in more.model.events] == ["gone", "late", "crate", "gone"]
    assert more.schedule.windows == loaded.schedule.windows
    assert more.schedule.last_tick == loaded.schedule.last_tick  # its overrides kept
