"""zenoh against ros2: lockstep ticks/s, nav wall time, and large-payload round trips.

    python -m bench.zenoh_chain [--repeats 3] [--seconds 3] [--skip-nav] [--skip-payload]

Prints, each measured side by side on this machine:
- ticks/s of a same-tick chain of 3 trivial counter nodes over zenoh (batched, the default),
  zenoh with ``--zenoh-express`` and ros2 (median of ``--repeats`` interleaved runs, full
  protocol: clock, status, sequence checks, digest), and CPU per tick of each process;
- nav.yaml without its camera: wall time multi-process (zenoh, ros2) over in-process;
- round trips/s of one sensor_msgs/Image of 1 KiB, 1 MiB and 4 MiB between two processes
  through the transport seam: ros2, zenoh with its default shared-memory optimisation,
  and zenoh with shared memory off (the run option zenoh_shm=False).
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

from bench.common import ROOT, bench_env, run_manifest, write_scenario
from bench.lockstep import chain

SIZES = (1024, 1 << 20, 4 << 20)


WAYS = {"zenoh": ("--transport", "zenoh"),
        "zenoh express": ("--transport", "zenoh", "--zenoh-express"),
        "ros2": ("--transport", "ros2")}
"""How the chain is run: zenoh (batched, the default), zenoh writing every message at once,
ros2."""


def chain_rates(repeats: int, seconds: int) -> dict[str, float]:
    """Median ticks/s of the 3-node chain per way of running it, runs interleaved."""
    rates: dict[str, list[float]] = {way: [] for way in WAYS}
    with tempfile.TemporaryDirectory() as tmp:
        path = write_scenario(chain(3, seconds), Path(tmp))
        for _ in range(repeats):
            for way in rates:
                rates[way].append(run_manifest(path, *WAYS[way])["ticks_per_s"])
    return {t: statistics.median(v) for t, v in rates.items()}


def chain_cpu_per_tick(seconds: int) -> dict[str, dict[str, float]]:
    """CPU microseconds per tick of the 3-node chain per process (orchestrator and nodes),
    per way of running it, from runs of 1 s and 1 + ``seconds`` s: the difference cancels
    the start-up cost, and CPU time, unlike ticks/s, depends less on what else the machine is
    doing (still: take several rounds on a loaded machine)."""
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        for way, args in WAYS.items():
            cpu, ticks = [], []
            for secs in (1, 1 + seconds):
                doc = chain(3, secs)
                doc["name"] = f"chain3_{secs}s"
                m = run_manifest(write_scenario(doc, Path(tmp)), *args)
                cpu.append({"orchestrator": m["orchestrator"]["cpu_s"],
                            **{n: v["cpu_s"] for n, v in m["nodes"].items()}})
                ticks.append(m["ticks"])
            out[way] = {p: (cpu[1][p] - cpu[0][p]) / (ticks[1] - ticks[0]) * 1e6
                        for p in cpu[0]}
    return out


def nav_without_camera(repeats: int) -> dict[str, float]:
    """Median wall seconds of nav.yaml without the camera node, per way of running."""
    doc = yaml.safe_load((ROOT / "scenarios" / "nav.yaml").read_text())
    doc["nodes"] = [n for n in doc["nodes"] if n["name"] != "camera"]
    doc["world"] = str(ROOT / "scenarios" / doc["world"])
    doc["name"] = "nav_nocamera"
    walls: dict[str, list[float]] = {"in-process": [], "zenoh": [], "ros2": []}
    with tempfile.TemporaryDirectory() as tmp:
        path = write_scenario(doc, Path(tmp))
        for _ in range(repeats):
            for way in walls:
                args = ("--in-process",) if way == "in-process" else ("--transport", way)
                walls[way].append(run_manifest(path, *args)["wall_time_s"])
    return {w: statistics.median(v) for w, v in walls.items()}


def payload_round_trips(transport: str, size: int, count: int, shm: bool = True) -> float:
    """Round trips/s of an Image of ``size`` bytes out and back between two processes."""
    from sensor_msgs.msg import Image

    from plan.options import TransportSettings
    from runtime.transport.factory import create_transport

    settings = TransportSettings(kind=transport, zenoh_shm=shm)
    t = create_transport(settings, "bench_ping")
    pub = t.publisher("/bench/ping", Image, 10)
    sub = t.subscription("/bench/pong", Image, 10)
    echo = subprocess.Popen([sys.executable, "-m", "bench.zenoh_chain", "--echo", transport,
                             str(count), str(int(shm))], env=dict(os.environ), cwd=ROOT)
    try:
        while pub.matched() < 1 or sub.matched() < 1:
            t.wait(10_000_000)
        data = _image_bytes(size)
        start = time.perf_counter()
        for _ in range(count):
            pub.publish(data)
            while not t.wait(1_000_000_000):
                pass
        rate = count / (time.perf_counter() - start)
    finally:
        echo.wait(timeout=30)
        t.close()
    return rate


def _image_bytes(size: int) -> bytes:
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import Image

    width = size // 3 // 64 or 1
    return serialize_message(Image(height=64, width=width, encoding="rgb8", step=3 * width,
                                   data=bytes(64 * 3 * width)))


def echo(transport: str, count: int, shm: bool = True) -> None:
    """The far end of payload_round_trips: send back every message received."""
    from sensor_msgs.msg import Image

    from plan.options import TransportSettings
    from runtime.transport.factory import create_transport

    t = create_transport(TransportSettings(kind=transport, zenoh_shm=shm), "bench_pong")
    pub = t.publisher("/bench/pong", Image, 10)
    t.subscription("/bench/ping", Image, 10)
    done = 0
    while done < count:
        for rec in t.wait(1_000_000_000):
            pub.publish(rec.data)
            done += 1
    time.sleep(0.2)  # let the last reply go out before the session closes
    t.close()


def main(argv: list[str] | None = None) -> None:
    """Run every measurement and print a table."""
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--seconds", type=int, default=3, help="sim seconds of the chain at 1 kHz")
    p.add_argument("--skip-nav", action="store_true")
    p.add_argument("--skip-payload", action="store_true")
    p.add_argument("--echo", nargs=3, help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.echo:
        echo(args.echo[0], int(args.echo[1]), bool(int(args.echo[2])))
        return
    os.environ.setdefault("ROS_DOMAIN_ID", bench_env()["ROS_DOMAIN_ID"])
    print(f"machine: {os.cpu_count()} CPUs")
    rates = chain_rates(args.repeats, args.seconds)
    for way, rate in rates.items():
        print(f"chain3 over {way:13s} (ticks/s, median of {args.repeats}) {rate:10.0f}")
    print(f"chain3 zenoh / ros2 {rates['zenoh'] / rates['ros2']:.2f}  "
          f"(zenoh express / ros2 {rates['zenoh express'] / rates['ros2']:.2f})")
    for way, per in chain_cpu_per_tick(args.seconds).items():
        parts = "  ".join(f"{p} {us:.0f}" for p, us in per.items())
        print(f"chain3 over {way:13s} CPU per tick (us): all {sum(per.values()):6.0f}  "
              f"({parts})")
    if not args.skip_nav:
        walls = nav_without_camera(args.repeats)
        for way, wall in walls.items():
            print(f"nav without camera, {way:10s} wall (s) {wall:7.2f}   "
                  f"{wall / walls['in-process']:.2f} x in-process")
    if not args.skip_payload:
        for size in SIZES:
            count = 2000 if size < 65536 else 200
            for name, transport, shm in (("ros2", "ros2", True), ("zenoh shm", "zenoh", True),
                                         ("zenoh no shm", "zenoh", False)):
                rate = payload_round_trips(transport, size, count, shm)
                print(f"Image {size:8d} B round trips/s over {name:12s} {rate:10.0f}")


if __name__ == "__main__":
    main()
