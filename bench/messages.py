"""Message cost: a 640x480 rgb8 image, a 32FC1 depth image and a 32k-point PointCloud2.

    python -m bench.messages

For each: build + serialise (+ canonicalise) in this process, then a round trip of the
CDR bytes to a second process and back over the transport, beside the round trip of an
8-byte message measured in the same run. Also the cost of handing rclpy a Python list
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
from sensor_msgs.msg import Image, PointCloud2, PointField
from std_msgs.msg import Int64

from bench.common import bench_env
from nodes.cdr import canonical_cdr

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
            "Image 640x480 32FC1": depth, "PointCloud2 32k points": cloud}


def timed(fn, repeats: int) -> float:
    """Mean ms of ``fn()``."""
    start = time.perf_counter()
    for _ in range(repeats):
        fn()
    return (time.perf_counter() - start) / repeats * 1e3


def round_trip_ms(transport, pub, data: bytes, repeats: int) -> float:
    """Mean ms for ``data`` to go to the echo process and come back."""
    start = time.perf_counter()
    for _ in range(repeats):
        pub.publish(data)
        if not transport.wait(10_000_000_000):
            raise TimeoutError("no echo within 10 s (is the echo process gone?)")
    return (time.perf_counter() - start) / repeats * 1e3


def echo(count: int) -> None:
    """The second process: send back every message received."""
    from nodes.transport_ros2 import Ros2Transport

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


def main() -> list[tuple[str, float, float, float]]:
    """Print the table; returns (message, serialise ms, round trip ms, list ms) rows."""
    from nodes.transport_ros2 import Ros2Transport

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
        ser = timed(lambda m=msg: canonical_cdr(serialize_message(m), type(m)), repeats)
        data = serialize_message(msg)
        deser = timed(lambda d=data, m=msg: deserialize_message(d, type(m)), repeats)
        try:
            rtt = round_trip_ms(t, pub, data, repeats)
        except TimeoutError as exc:
            print(f"{name}: round trip not measured: {exc}")
            rtt = math.nan
        as_list = list_cost(msg)
        rows.append((name, ser, deser, rtt, as_list))
    try:
        child.wait(timeout=60)
    except subprocess.TimeoutExpired:
        child.kill()
    t.close()
    floor = rows[0][3]
    print(f"{'message':26s} {'serialise':>10s} {'deserialise':>12s} {'round trip':>11s}"
          f" {'x 8-byte':>9s} {'data as list':>13s}")
    for name, ser, deser, rtt, as_list in rows:
        listed = f"{as_list:10.2f} ms" if as_list else "         -"
        print(f"{name:26s} {ser:8.3f} ms {deser:9.3f} ms {rtt:8.3f} ms {rtt / floor:9.1f}"
              f" {listed}")
    return rows


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
