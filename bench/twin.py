"""The digital twin's mirror delay on loopback: a synthetic robot (a rosbridge server in
this process that publishes nav_msgs/Odometry on /odom, stamped with this machine's clock,
so the delay is absolute) and `cosim-orchestrate scenarios/twin.yaml --twin ...` following
it, at 50 Hz and then at higher robot rates.

Per rate: the delay from the robot's stamp to the message's arrival in the twin (p50, p99),
the mirror delay from the stamp to the tick it entered (p50, p99: what the twin lags the
robot by; up to one 20 ms tick more than the arrival), messages lost and superseded (more
than one per tick: only the latest enters), and the first rate at which the arrival delay
grows (p50 over twice the 50 Hz one). The twin runs --in-process (the transport is not what
is measured) for --seconds of wall time per rate.

    .venv/bin/python -m bench.twin [--rates 50 100 200 500 1000] [--seconds 10]

Figures: still to be taken on an idle machine.
"""

from __future__ import annotations

import argparse
import json
import socket
import tempfile
import threading
import time
from pathlib import Path

from bench.common import ROOT, run_manifest

TWIN = ROOT / "scenarios" / "twin.yaml"


class SyntheticRobot:
    """A rosbridge server that publishes /odom at ``rate`` Hz to whoever subscribes."""

    def __init__(self, rate: float):
        from websockets.sync.server import serve

        self.period = 1.0 / rate
        with socket.socket() as probe:
            probe.bind(("127.0.0.1", 0))
            self.port = probe.getsockname()[1]
        self.server = serve(self._client, "127.0.0.1", self.port)
        self.thread = threading.Thread(target=self.server.serve_forever, daemon=True)
        self.thread.start()
        self.sent = 0

    def _client(self, ws) -> None:
        subscribed = threading.Event()

        def read() -> None:
            for frame in ws:
                request = json.loads(frame)
                if request.get("op") == "subscribe" and request.get("topic") == "/odom":
                    subscribed.set()

        threading.Thread(target=read, daemon=True).start()
        subscribed.wait()
        k, start, wall_start = 0, time.monotonic(), time.time()
        x = 0.0
        while True:
            k += 1
            due = start + k * self.period
            time.sleep(max(0.0, due - time.monotonic()))
            now = wall_start + k * self.period  # stamped when measured, as a sensor does
            x += 0.3 * self.period
            msg = {"header": {"stamp": {"sec": int(now), "nanosec": int(now % 1 * 1e9)},
                              "frame_id": "odom"},
                   "child_frame_id": "base_link",
                   "pose": {"pose": {"position": {"x": -3.0 + x, "y": -3.0, "z": 0.0},
                                     "orientation": {"w": 1.0}}}}
            try:
                ws.send(json.dumps({"op": "publish", "topic": "/odom", "msg": msg}))
            except Exception:  # noqa: BLE001 - the twin went away: this client is done
                return
            self.sent += 1

    def close(self) -> None:
        """Stop serving."""
        self.server.shutdown()


def one_rate(rate: float, seconds: float, out: Path) -> dict:
    """The twin's figures for /odom at ``rate`` Hz."""
    robot = SyntheticRobot(rate)
    try:
        manifest = run_manifest(TWIN, "--twin", f"ws://127.0.0.1:{robot.port}", "--in-process",
                                "--duration", f"{int(seconds * 1000)}ms", out=out)
    finally:
        robot.close()
    odom = manifest["live"]["twin"]["topics"]["/odom"]
    return {"rate_hz": rate, "sent": robot.sent, **{k: odom[k] for k in (
        "arrived", "entered", "superseded", "lost", "clock", "delay", "mirror_delay")}}


def main(argv: list[str] | None = None) -> None:
    """Run every rate; print one line per rate and where the delay starts to grow."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--rates", type=float, nargs="+", default=[50, 100, 200, 500, 1000])
    p.add_argument("--seconds", type=float, default=10.0)
    args = p.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for rate in args.rates:
            row = one_rate(rate, args.seconds, Path(tmp))
            rows.append(row)
            d, m = row["delay"] or {}, row["mirror_delay"] or {}
            print(f"{rate:7.0f} Hz: arrival delay p50 {d.get('p50_ms')} ms p99 {d.get('p99_ms')}"
                  f" ms; mirror delay p50 {m.get('p50_ms')} ms p99 {m.get('p99_ms')} ms; sent "
                  f"{row['sent']}, arrived {row['arrived']}, entered {row['entered']}, "
                  f"superseded {row['superseded']}, lost {row['lost']} (clock {row['clock']})",
                  flush=True)
    base = (rows[0]["delay"] or {}).get("p50_ms")
    grows = next((r["rate_hz"] for r in rows[1:] if base and r["delay"]
                  and r["delay"]["p50_ms"] > 2 * base), None)
    print(f"the arrival delay grows (p50 over twice {base} ms) from: "
          f"{f'{grows:.0f} Hz' if grows else 'no rate tried'}")


if __name__ == "__main__":
    main()
