"""The rates ROS sensors use: a camera at 30 Hz and a lidar at 15 Hz with physics at 50 Hz.

Their periods are not whole nanoseconds; the schedule counts ticks of 1/150 s exactly and
stamps tick ``k`` at ``k * 10**9 / 150`` ns rounded half up, once, in every mode.
"""

from __future__ import annotations

import math
from fractions import Fraction

import yaml

from orchestrator.outputs.bag import BagReader
from tests.helpers import nav_without_camera_doc, orchestrate

CAMERA = "/camera/color/image_raw"
RATES = {"/clock": 150, "/scan": 15, CAMERA: 30, "/camera/camera_info": 30, "/odom": 50}


def half_up(n: int, rate: int) -> int:
    """The n-th time of a rate in whole ns, rounded half up (what docs/concepts/schedule.md
    says a stamp is), computed here apart from the code under test."""
    return math.floor(Fraction(n * 10**9, rate) + Fraction(1, 2))


def ros_rates_scenario(tmp_path):
    """nav, one second, with its lidar at 15 Hz and a small camera at 30 Hz."""
    doc = nav_without_camera_doc("1s")
    doc["name"] = "ros_rates"
    for node in doc["nodes"]:
        if node["name"] == "lidar":
            node["rate"] = 15
    doc["nodes"].append({"name": "camera", "kind": "sensors", "rate": 30,
                         "params": {"camera": {"width": 32, "height": 24, "depth": False}},
                         "inputs": [{"topic": "/cosim/world_state", "mode": "same_tick"}]})
    path = tmp_path / "ros_rates.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def test_30_and_15_hz_run_with_one_digest_and_rounded_stamps(tmp_path):
    scenario = ros_rates_scenario(tmp_path)
    local = orchestrate(scenario, tmp_path / "local", "--in-process")
    assert local.code in (0, 1), local.stderr  # one second does not reach nav's goal
    assert local.manifest["tick_ns"] == "20000000/3"  # 1/150 s, exact
    remote = orchestrate(scenario, tmp_path / "remote")
    assert remote.code == local.code, remote.stderr
    assert remote.manifest["digest"] == local.manifest["digest"]
    assert remote.manifest["topic_digests"] == local.manifest["topic_digests"]
    with BagReader(remote.run_dir / "bag") as bag:
        for topic, rate in RATES.items():
            logged = list(bag.messages(topic))
            want = [half_up(n, rate) for n in range(rate + 1)]  # 0 .. 1 s inclusive
            assert [t for t, _ in logged] == want, topic
            if topic == "/clock":
                stamps = [m.clock.sec * 10**9 + m.clock.nanosec for _, m in logged]
            else:
                stamps = [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec
                          for _, m in logged]
            assert stamps == want, topic
    assert [half_up(n, 30) for n in range(4)] == [0, 33_333_333, 66_666_667, 100_000_000]
    assert [half_up(n, 50) for n in range(3)] == [0, 20_000_000, 40_000_000]  # whole, as ever


def test_a_duration_at_a_ticks_rounded_time_loads_as_that_tick(tmp_path):
    """A replay of a run stopped early ends at its last tick's stamp, rounded to whole ns
    (orchestrator.replay): with a 1/150 s tick that is rarely a multiple of anything, and it
    must load as that tick; a time between two ticks' stamps is still refused."""
    import pytest

    from descriptions.load import load_scenario
    from plan.errors import ScenarioError

    path = ros_rates_scenario(tmp_path)
    for k in (100, 101, 102):
        scenario = load_scenario(path, {"duration": f"{half_up(k, 150)}ns"})
        assert scenario.schedule.last_tick == k
    with pytest.raises(ScenarioError, match="not a whole number of 1/150s ticks"):
        load_scenario(path, {"duration": f"{half_up(101, 150) + 1}ns"})
