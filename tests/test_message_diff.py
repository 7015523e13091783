"""--against names the first field that differs, with both values: on messages, on
serialised messages, on two crafted bags and end to end on two runs with different seeds."""

from __future__ import annotations

import math

from geometry_msgs.msg import Pose, PoseArray, Twist
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore
from sensor_msgs.msg import LaserScan

from orchestrator.api import run
from orchestrator.outputs.diff import (
    Difference,
    bag_entries,
    first_difference,
    message_at,
    run_bag,
    with_field,
)
from runtime.cdr.encode import encode
from runtime.message_diff import field_difference, serialized_difference
from tests.helpers import SCENARIOS, orchestrate

PROTOCOL = SCENARIOS / "protocol.yaml"
TICK = 20_000_000


def poses(n: int, **at: float) -> PoseArray:
    """n poses at the origin; ``at`` = {index_x: x} moves pose ``index`` along x."""
    msg = PoseArray(poses=[Pose() for _ in range(n)])
    for key, x in at.items():
        msg.poses[int(key.split("_")[1])].position.x = x
    return msg


def test_the_first_field_that_differs_is_named_with_both_values():
    a, b = Twist(), Twist()
    a.angular.x, b.angular.x = 6.91e-310, 6.95e-310  # uninitialised doubles, say
    assert field_difference(a, b).describe() == "angular.x: 6.91e-310 vs 6.95e-310"
    assert field_difference(a, a) is None
    found = field_difference(poses(5), poses(5, at_3=1.5))
    assert (found.path, found.first, found.second) == ("poses[3].position.x", 0.0, 1.5)
    assert field_difference(poses(5), poses(4)).describe() == "poses: 5 elements vs 4"
    scan, other = LaserScan(ranges=[1.0] * 4), LaserScan(ranges=[1.0] * 4)
    other.ranges[2] = 0.1  # float32: shown as float32, not as the double nearest it
    assert field_difference(scan, other).describe() == "ranges[2]: 1.0 vs 0.1"
    zero, negative = Twist(), Twist()
    negative.linear.y = -0.0  # a digest hashes bits: 0.0 and -0.0 differ
    assert field_difference(zero, negative).describe() == "linear.y: 0.0 vs -0.0"
    nan = Twist()
    nan.linear.z = math.nan
    assert field_difference(nan, nan) is None


def test_serialised_messages_are_decoded_and_compared():
    a, b = Twist(), Twist()
    b.linear.x = 0.25
    assert serialized_difference(encode(a), encode(b), Twist).describe() == \
        "linear.x: 0.0 vs 0.25"
    assert serialized_difference(encode(a), encode(a), Twist) is None


def test_rosbags_objects_compare_too():
    # a type not installed here is read with the bag's own definition, as rosbags objects
    store = get_typestore(Stores.ROS2_JAZZY)
    scan, other = LaserScan(ranges=[1.0] * 4), LaserScan(ranges=[1.0] * 4)
    other.ranges[2] = 0.5
    a, b = (store.deserialize_cdr(encode(m), "sensor_msgs/msg/LaserScan") for m in (scan, other))
    assert field_difference(a, b).describe() == "ranges[2]: 1.0 vs 0.5"


def write_bag(path, messages):
    """A rosbag2 (MCAP) of /poses messages [(tick, PoseArray)], as cosim writes one."""
    store = get_typestore(Stores.ROS2_JAZZY)
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        conn = writer.add_connection("/poses", "geometry_msgs/msg/PoseArray", typestore=store)
        for tick, msg in messages:
            writer.write(conn, tick * TICK, encode(msg))
    return path


def test_two_bags_that_differ_in_one_field(tmp_path):
    reference = write_bag(tmp_path / "a", [(0, poses(5)), (1, poses(5)), (2, poses(5))])
    actual = write_bag(tmp_path / "b", [(0, poses(5)), (1, poses(5, at_3=0.5)), (2, poses(5))])
    diff = first_difference(bag_entries(reference, TICK), bag_entries(actual, TICK), TICK)
    assert diff == Difference(1, "/poses", "differs", TICK)
    named = with_field(diff, reference, actual)
    assert named.describe() == \
        "topic /poses at tick 1 (t = 0.020 s): poses[3].position.x: 0.0 vs 0.5"
    assert with_field(diff, reference, reference).field.endswith("(padding)")


def test_against_names_the_field_and_both_values_end_to_end(tmp_path):
    reference = run(PROTOCOL, in_process=True, seed=3, duration="0.1s", out=tmp_path / "ref",
                    picture=False)
    other = orchestrate(PROTOCOL, tmp_path / "other", "--in-process", "--seed", "4",
                        "--duration", "0.1s", "--quiet", "--against", str(reference.run_dir))
    assert other.code == 4, other.stderr
    # /loop sorts first of the topics the seeded noise reaches at tick 0
    theirs = message_at(run_bag(reference.run_dir), "/loop", 0, TICK)
    mine = message_at(run_bag(other.run_dir), "/loop", 0, TICK)
    assert theirs.data != mine.data
    assert (f"topic /loop at tick 0 (t = 0.000 s): data: {theirs.data!r} vs {mine.data!r}."
            in other.stderr), other.stderr
