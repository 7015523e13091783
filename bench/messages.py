"""Message cost: a 640x480 rgb8 image, a 32FC1 depth image and a 32k-point PointCloud2.

    python -m bench.messages

For each: serialise with rclpy (+ zeroing the padding) and with cosim's generated encoder
(``runtime.cdr.encode``, same bytes), deserialise with rclpy and with the generated decoder
(``runtime.cdr.decode``, same objects), then a round trip of the CDR bytes to a second process
and back over the transport, beside the round trip of an 8-byte message measured in the
same run. The nav scenario's busiest messages (odometry, a 360-beam scan, a 123-pose plan)
are measured beside the images. Also the cost of handing rclpy a Python list
instead of bytes/array (rclpy converts sequences element by element: rclpy issue 763).
"""

from __future__ import annotations

import array
import math
import subprocess
import sys
import time

import numpy as np
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Image, LaserScan, PointCloud2, PointField
from std_msgs.msg import Int64

from bench.common import bench_env
from runtime.cdr.canonical import canonical_cdr
from runtime.cdr.decode import decode
from runtime.cdr.encode import encode

ECHO_TOPICS = ("/bench_msg_ping", "/bench_msg_pong")


def payloads() -> dict[str, object]:
    """The messages measured."""
    rgb = Image(height=480, width=640, encoding="rgb8", step=640 * 3,
                data=np.zeros(480 * 640 * 3, np.uint8).tobytes())
    depth = Image(height=480, width=640, encoding="32FC1", step=640 * 4,
                  data=np.ones(480 * 640, np.float32).tobytes())
    fields = [PointField(name=n, offset=4 * i, datatype=PointField.FLOAT32, count=1)
              for i, n in enumerate("x y z intensity".split())]
    cloud = PointCloud2(height=1, width=32768, fields=fields, point_step=16,
                        row_step=16 * 32768, is_dense=True,
                        data=np.zeros(32768 * 4, np.float32).tobytes())
    return {"Int64 (8 bytes)": Int64(data=1), "Image 640x480 rgb8": rgb,
            "Image 640x480 32FC1": depth, "PointCloud2 32k points": cloud, **nav_payloads()}


def nav_payloads() -> dict[str, object]:
    """Odometry, a 360-beam LaserScan and a 123-pose Path as the nav nodes build them."""
    from nodes.control.global_planner import path_message
    from nodes.physics.messages import odometry

    odom = odometry(np.array([1.0, 2.0, 0.1, 1.0, 0.0, 0.0, 0.0]), np.full(6, 0.1), "odom",
                    "base_link")
    scan = LaserScan(ranges=array.array("f", np.linspace(0.2, 8.0, 360, dtype=np.float32)))
    path = path_message(np.cumsum(np.full((123, 2), 0.1), axis=0), "map", 0.5)
    return {"Odometry": odom, "LaserScan 360 beams": scan, "Path 123 poses": path}


def timed(fn, repeats: int) -> float:
    """Mean ms of ``fn()``."""
    start = time.perf_counter()
    for _ in range(repeats):
        fn()
    return (time.perf_counter() - start) / repeats * 1e3


def round_trip_ms(transport, pub, data: bytes, repeats: int) -> float:
    """Mean ms for ``data`` to go to the echo process and come back. Echoes are counted,
    not wake-ups: a wait may return nothing (a spurious wake-up of the wait set) or two
    echoes at once, and treating either as one round trip put the two processes out of
    step (the cause of the 'no echo' failures inside make bench)."""
    start = time.perf_counter()
    for _ in range(repeats):
        pub.publish(data)
        deadline = time.monotonic() + 10.0
        echoed = 0
        while not echoed:
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError("no echo within 10 s (is the echo process gone?)")
            echoed = len(transport.wait(int(left * 1e9)))
    return (time.perf_counter() - start) / repeats * 1e3


def echo(count: int) -> None:
    """The second process: send back every message received."""
    from runtime.transport.ros2 import Ros2Transport

    t = Ros2Transport("bench_echo")
    pub = t.publisher(ECHO_TOPICS[1], Image, 10)
    t.subscription(ECHO_TOPICS[0], Image, 10)
    while pub.matched() < 1:
        t.wait(10_000_000)
    done = 0
    while done < count:
        for rec in t.wait(1_000_000_000):
            pub.publish(rec.data)
            done += 1
    t.close()


def main() -> list[tuple]:
    """Print the table; returns its rows (message, then the ms of each column)."""
    from runtime.transport.ros2 import Ros2Transport

    repeats = 30
    msgs = payloads()
    child = subprocess.Popen([sys.executable, "-m", "bench.messages", "echo",
                              str(repeats * len(msgs))], env=bench_env())
    t = Ros2Transport("bench_sender")
    pub = t.publisher(ECHO_TOPICS[0], Image, 10)
    sub = t.subscription(ECHO_TOPICS[1], Image, 10)
    while pub.matched() < 1 or sub.matched() < 1:
        t.wait(10_000_000)
    time.sleep(0.3)
    rows = []
    for name, msg in msgs.items():
        decode(encode(msg), type(msg))  # generate the encoder and decoder outside the timing
        ser = timed(lambda m=msg: canonical_cdr(serialize_message(m), type(m)), repeats)
        enc = timed(lambda m=msg: encode(m), repeats)
        data = serialize_message(msg)
        deser = timed(lambda d=data, m=msg: deserialize_message(d, type(m)), repeats)
        dec = timed(lambda d=data, m=msg: decode(d, type(m)), repeats)
        try:
            rtt = round_trip_ms(t, pub, data, repeats)
        except TimeoutError as exc:
            print(f"{name}: round trip not measured: {exc}")
            rtt = math.nan
        rows.append((name, ser, enc, deser, dec, rtt, list_cost(msg)))
    try:
        child.wait(timeout=60)
    except subprocess.TimeoutExpired:
        child.kill()
    t.close()
    print_rows(rows)
    return rows


def print_rows(rows: list[tuple]) -> None:
    """The table: ms per operation, rclpy beside cosim's generated code."""
    floor = rows[0][5]
    print(f"{'message':24s} {'rclpy ser':>10s} {'cosim enc':>10s} {'rclpy de':>10s}"
          f" {'cosim dec':>10s} {'round trip':>11s} {'x 8-byte':>9s} {'as list':>9s}  (ms)")
    for name, ser, enc, deser, dec, rtt, as_list in rows:
        listed = f"{as_list:9.2f}" if as_list else "        -"
        print(f"{name:24s} {ser:10.3f} {enc:10.3f} {deser:10.3f} {dec:10.3f} {rtt:11.3f}"
              f" {rtt / floor:9.1f} {listed}")


def list_cost(msg) -> float | None:
    """ms to build the message's data field from a Python list instead of bytes."""
    if not hasattr(msg, "data") or not isinstance(msg.data, (bytes, array.array, list)):
        return None
    values = list(bytes(msg.data))
    return timed(lambda: type(msg)(data=values), 3)


if __name__ == "__main__":
    if len(sys.argv) > 2 and sys.argv[1] == "echo":
        echo(int(sys.argv[2]))
    else:
        main()
