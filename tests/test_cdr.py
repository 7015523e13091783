"""canonical_cdr: equal messages give equal bytes, and the bytes still decode to the message."""

from __future__ import annotations

import array

import pytest
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped, Twist
from nav_msgs.msg import Odometry, Path
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import CameraInfo, Image, JointState, LaserScan, PointCloud2, PointField
from std_msgs.msg import Empty, Float64MultiArray, MultiArrayDimension, String

from runtime.cdr.canonical import canonical_cdr


def messages():
    """One of each layout the nav scenario publishes, padding included."""
    js = JointState(name=["pan_joint", "tilt", "left_wheel"], position=[1.0, 2.0, 3.0],
                    velocity=[], effort=[0.5])
    js.header.frame_id = "base_link"
    odom = Odometry(child_frame_id="base_link")
    odom.header.frame_id = "odom"
    odom.pose.pose.position.x = 1.5
    scan = LaserScan(ranges=array.array("f", [1.0, 2.0, float("inf")]))
    scan.header.frame_id = "laser"
    path = Path(poses=[PoseStamped() for _ in range(3)])
    path.poses[1].header.frame_id = "x"
    info = CameraInfo(distortion_model="plumb_bob", d=[0.0] * 5)
    cloud = PointCloud2(height=1, width=2, point_step=8, row_step=16, data=bytes(16), fields=[
        PointField(name="x", offset=0, datatype=7, count=1),
        PointField(name="intensity", offset=4, datatype=7, count=1)])
    multi = Float64MultiArray(data=[1.0, 2.0])
    multi.layout.dim = [MultiArrayDimension(label="qpos", size=2, stride=2)]
    return [js, odom, scan, path, info, cloud, multi, Twist(), Empty(), String(data="abc"),
            Clock(), Image(height=2, width=3, encoding="rgb8", step=9, data=bytes(range(18))),
            DiagnosticStatus(name="a", values=[KeyValue(key="k", value="v")])]


@pytest.mark.parametrize("msg", messages(), ids=lambda m: type(m).__name__)
def test_canonical_bytes_are_stable_and_decode_to_the_message(msg):
    seen = set()
    for size in range(1, 300, 7):
        garbage = [bytearray(b"\xab" * size) for _ in range(5)]  # dirty the allocator
        raw = serialize_message(msg)
        del garbage
        canonical = canonical_cdr(raw, type(msg))
        assert len(canonical) == len(raw)
        assert deserialize_message(canonical, type(msg)) == msg
        seen.add(canonical)
    assert len(seen) == 1


def test_padding_is_zero():
    msg = JointState(name=["ab"], position=[1.0])
    canonical = canonical_cdr(serialize_message(msg), JointState)
    # header: stamp (8) + frame_id '' (4 + 1 byte) then 3 padding bytes before name's count
    assert canonical[4 + 8 + 4 + 1: 4 + 8 + 4 + 4] == b"\0\0\0"
