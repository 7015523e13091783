"""A bare rclpy ping-pong (no cosim protocol): the floor for lockstep latency."""

from __future__ import annotations

import sys
import time

from rclpy.serialization import serialize_message
from std_msgs.msg import Int64

from runtime.transport.ros2 import Ros2Transport


def main() -> None:
    """`ping N` prints round trips/s; `pong N` answers N pings."""
    role, n = sys.argv[1], int(sys.argv[2])
    t = Ros2Transport(f"bench_{role}")
    pub = t.publisher("/bench_ping" if role == "ping" else "/bench_pong", Int64, 10)
    sub = t.subscription("/bench_pong" if role == "ping" else "/bench_ping", Int64, 10)
    while pub.matched() < 1 or sub.matched() < 1:
        t.wait(10_000_000)
    data = serialize_message(Int64(data=1))
    if role == "ping":
        time.sleep(0.3)
        start = time.perf_counter()
        for _ in range(n):
            pub.publish(data)
            while not t.wait(1_000_000_000):
                pass
        print(f"round_trips_per_s {n / (time.perf_counter() - start):.1f}")
    else:
        got = 0
        while got < n:
            for _ in t.wait(1_000_000_000):
                pub.publish(data)
                got += 1
    t.close()


if __name__ == "__main__":
    main()
