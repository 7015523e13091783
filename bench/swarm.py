"""Many robots: real-time factor, cost over in-process and memory per robot, every packing.

    python -m bench.swarm [--robots 1 4 16 64 256] [--seconds 5] [--spread N] [--out swarm.json]

For each robot count N: an open arena sized to hold N robots (walls only, so the cost is
the swarm's own), N robots placed from the seed with goals mirrored through the centre,
a lidar (180 beams, 10 Hz) and the built-in controller (10 Hz) per robot, one physics node
(50 Hz) for the world. It runs for a fixed simulated time (no early stop) with every
packing: one process per node (``none``; skipped above ``--max-processes``), ``--pack
kind`` (the world node, every lidar, every controller: 3 processes), ``spread`` (``--pack
kind --spread N``: the lidars over N processes and the controllers over N, N = bench's
``--spread``, by default half the cores less one), ``--pack robot`` (one process per robot plus the
world's) and ``--in-process`` (the reference). Per run:
real-time factor (sim s / wall s of the whole command, run without its report.png:
``--no-picture``), wall over the in-process wall,
peak memory per robot (every process's peak RSS summed, over N: forked node processes share
the orchestrator's pages, which this counts once per process) and PSS per robot (every
process's proportional set size just before the nodes stop, summed, over N: shared pages
counted once), whether the digest equals
the in-process one, where the step time goes (physics, lidars, controllers: summed over
the nodes of each kind) and the tick loop's wall over the physics node's own step time
(the one serial part of a tick: what spreading the other nodes over cores can reach). The
floor is shared/notes/swarm-physics-floor.md (MuJoCo alone).

Figures mean something only on an otherwise idle machine.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import tempfile
import threading
from pathlib import Path

import psutil

from bench.common import ROOT, run_manifest, write_scenario

PACKINGS = ("none", "kind", "spread", "robot", "in-process")
SPREAD = max(1, ((os.cpu_count() or 2) - 2) // 2)  # lidars and controllers: 2N + physics
CLEARANCE = 0.8  # m between robot starts (the robots are 0.44 m across)


def arena_xml(half: float) -> str:
    """A square walled arena of half-width ``half`` metres, no obstacles, no robot."""
    w = half + 0.05
    walls = "\n".join(
        f'    <geom name="wall_{n}" type="box" group="0" pos="{x} {y} 0.5" size="{sx} {sy} 0.5"/>'
        for n, x, y, sx, sy in (("n", 0, w, w + 0.05, 0.05), ("s", 0, -w, w + 0.05, 0.05),
                                ("e", w, 0, 0.05, w + 0.05), ("w", -w, 0, 0.05, w + 0.05)))
    return f"""<mujoco model="bench_arena">
  <option timestep="0.002" integrator="implicitfast"/>
  <visual><quality shadowsize="0"/><map znear="0.01" zfar="200"/></visual>
  <worldbody>
    <light pos="0 0 6" dir="0 0 -1" directional="true" castshadow="false"/>
    <geom name="floor" type="plane" size="{w + 1} {w + 1} 0.1"/>
{walls}
  </worldbody>
</mujoco>
"""


def scenario(n: int, seconds: float, directory: Path, physics_threads: int = 1) -> Path:
    """The N-robot scenario, its arena written beside it; the physics node steps with
    ``physics_threads`` threads of MuJoCo's engine pool (the same digest at any count)."""
    # room for n robots CLEARANCE apart with seeded draws: about 3 x their packed area
    half = max(3.0, math.sqrt(3.0 * n) * CLEARANCE / 2 + 0.6)
    world = directory / f"arena_{n}.xml"
    world.write_text(arena_xml(half))
    region = [-(half - 0.4), half - 0.4]
    doc = {
        "name": f"swarm{n}", "seed": 1, "duration": f"{seconds}s", "world": str(world),
        "robots": {"description": str(ROOT / "scenarios" / "worlds" / "robot.xml"),
                   "count": n, "region": {"x": region, "y": region},
                   "clearance": CLEARANCE},
        "success": {"reach_goal": False, "max_collisions": 1_000_000, "stop_on_goal": False},
        "deadlines": {"start": "600s", "tick": "120s"},
        "nodes": [
            {"name": "physics", "kind": "physics", "rate": 50,
             "params": {"imu": None, "threads": physics_threads},
             "inputs": [{"topic": "/cmd_vel", "mode": "delayed"}]},
            {"name": "lidar", "kind": "sensors", "for_each": "robot", "rate": 10,
             "params": {"lidar": {"beams": 180, "range_max": 8.0}},
             "inputs": [{"topic": "/cosim/world_state", "mode": "same_tick"}]},
            {"name": "control", "kind": "control", "for_each": "robot", "rate": 10,
             "inputs": [{"topic": "/odom", "mode": "same_tick"},
                        {"topic": "/scan", "mode": "same_tick"}]}],
    }
    return write_scenario(doc, directory)


def processes(n: int, packing: str, spread: int = SPREAD) -> int:
    """How many node processes a packing starts."""
    return {"none": 1 + 2 * n, "kind": 3, "spread": 1 + 2 * min(spread, n), "robot": 1 + n,
            "in-process": 0}[packing]


def peak_mb(manifest: dict) -> float:
    """Peak RSS of the orchestrator and every node process (each process once), MB."""
    by_pid = {e["pid"]: e.get("peak_rss_mb", 0.0) for e in manifest["nodes"].values()
              if "pid" in e}
    return manifest["orchestrator"]["peak_rss_mb"] + sum(by_pid.values())


def pss_mb(manifest: dict) -> float | None:
    """PSS of the orchestrator and every node process (each process once) at the run's end,
    MB: a page the processes share (forked nodes share the orchestrator's copy-on-write) is
    divided among them, where summed RSS counts it once per process. None without figures."""
    own = manifest["orchestrator"].get("end_pss_mb")
    if own is None:
        return None
    by_pid = {e["pid"]: e.get("end_pss_mb", 0.0) for e in manifest["nodes"].values()
              if "pid" in e}
    return own + sum(by_pid.values())


def where_time_goes(manifest: dict) -> dict[str, float]:
    """In-process step seconds by kind of node: physics, lidars, controllers."""
    out = {"physics": 0.0, "lidar": 0.0, "control": 0.0}
    for name, e in manifest["nodes"].items():
        kind = name.partition("@")[0]
        if kind in out and "step_ms_mean" in e:
            out[kind] += e["ticks"] * e["step_ms_mean"] / 1e3
    return out


def dds_participants() -> set[tuple[int, int]]:
    """(domain, participant id) of every DDS participant of this process's descendants (the
    run it started): each binds its metatraffic unicast port 7410 + 250 * domain + 2 * id
    and its user unicast port, one above (RTPS 9.6.1.1); the pair tells it from ephemeral
    ports."""
    ours = {p.pid for p in psutil.Process().children(recursive=True)}
    bound = {(c.pid, c.laddr.port) for c in psutil.net_connections(kind="udp") if c.pid in ours}
    out = set()
    for pid, port in bound:
        offset = port - 7410
        if 0 <= offset < 250 * 233 and offset % 250 % 2 == 0 and (pid, port + 1) in bound:
            out.add((offset // 250, offset % 250 // 2))
    return out


class ParticipantCount:
    """The most DDS participants the run started by this process held at once (sampled
    every 0.2 s in a thread while the block runs)."""

    def __enter__(self) -> ParticipantCount:
        self.most = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._sample, daemon=True)
        self._thread.start()
        return self

    def _sample(self) -> None:
        while not self._stop.wait(0.2):
            self.most = max(self.most, len(dds_participants()))

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join()


def run(n: int, packing: str, path: Path, out: Path, spread: int = SPREAD) -> dict:
    """One run's figures."""
    args = {"none": ("--pack", "node"), "kind": ("--pack", "kind"),
            "spread": ("--pack", "kind", "--spread", str(spread)),
            "robot": ("--pack", "robot"), "in-process": ("--in-process",)}[packing]
    with ParticipantCount() as participants:  # the loop is measured, not the report's picture
        m = run_manifest(path, *args, "--no-picture", out=out)
    split = where_time_goes(m)
    return {"robots": n, "packing": packing, "status": m["outcome"]["status"],
            "digest": m["digest"], "wall_s": m["wall_time_s"], "loop_s": m["loop_s"],
            "real_time_factor": m["real_time_factor"],
            "startup_s": (m.get("startup") or {}).get("command_to_first_tick_s"),
            "loop_real_time_factor": m["loop_real_time_factor"],
            "peak_mb_per_robot": round(peak_mb(m) / n, 1),
            "pss_mb_per_robot": (round(pss_mb(m) / n, 2) if pss_mb(m) is not None else None),
            "dds_participants": participants.most,
            "time_s": split,
            "loop_over_physics": (round(m["loop_s"] / split["physics"], 2)
                                  if split["physics"] > 0 else None),
            "collisions_robots": (m.get("swarm") or {}).get("totals", {}).get(
                "collisions_robots")}


def main(argv: list[str] | None = None) -> list[dict]:
    """Run every robot count with every packing; print a table; optionally write JSON."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", type=int, nargs="+", default=[1, 4, 16, 64, 256])
    parser.add_argument("--seconds", type=float, default=5.0, help="simulated seconds per run")
    parser.add_argument("--packings", nargs="+", default=list(PACKINGS), choices=PACKINGS)
    parser.add_argument("--spread", type=int, default=SPREAD,
                        help="spread: the processes for the lidars, and for the controllers")
    parser.add_argument("--physics-threads", type=int, default=1,
                        help="MuJoCo engine threads of the physics node (params.threads): "
                             "the step of one world on more cores, the same digest")
    parser.add_argument("--max-processes", type=int, default=70,
                        help="skip a packing that would start more node processes")
    parser.add_argument("--out", type=Path, help="write every row as JSON here")
    a = parser.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory(prefix="cosim-bench-swarm-") as tmp:
        tmp = Path(tmp)
        for n in a.robots:
            path = scenario(n, a.seconds, tmp, a.physics_threads)
            order = ["in-process", *[p for p in a.packings if p != "in-process"]]
            reference = None
            for packing in order:
                if packing not in a.packings and packing != "in-process":
                    continue
                if processes(n, packing, a.spread) > a.max_processes:
                    rows.append({"robots": n, "packing": packing, "status": "skipped",
                                 "why": f"{processes(n, packing, a.spread)} processes > "
                                        f"--max-processes {a.max_processes}"})
                    continue
                row = run(n, packing, path, tmp / "runs", a.spread)
                if reference is None:
                    reference = row
                row["wall_over_in_process"] = round(row["wall_s"] / reference["wall_s"], 2)
                row["digest_equal"] = row["digest"] == reference["digest"]
                rows.append(row)
                print(line(row), flush=True)
    for row in rows:
        if row["status"] == "skipped":
            print(f"{row['robots']:>5} {row['packing']:<11} skipped: {row['why']}")
    if a.out:
        a.out.write_text(json.dumps(rows, indent=2) + "\n")
    return rows


def line(row: dict) -> str:
    """One printed row."""
    text = (f"{row['robots']:>5} {row['packing']:<11} {row['status']:<8} "
            f"RTF {_f(row['real_time_factor'], '>6')} "
            f"(loop {_f(row['loop_real_time_factor'], '>6')})  "
            f"wall {_f(row['wall_s'], '>7.2f')} s = {_f(row['wall_over_in_process'], '>5.2f')}x "
            f"in-process  start-up {_f(row['startup_s'], '>6.2f')} s  "
            f"{_f(row['peak_mb_per_robot'], '>7.1f')} MB/robot peak RSS "
            f"({_f(row['pss_mb_per_robot'], '>6.2f')} PSS at end)  "
            f"{row['dds_participants']:>3} DDS participants  digest "
            f"{'=' if row['digest_equal'] else 'DIFFERS'}")
    if row["time_s"]:
        t = row["time_s"]
        text += (f"  steps: physics {t['physics']:.2f} s, lidars {t['lidar']:.2f} s, "
                 f"controllers {t['control']:.2f} s; loop/physics "
                 f"{_f(row['loop_over_physics'], '.2f')}")
    return text


def _f(value, spec: str) -> str:
    """A figure, or '-' when the run did not give it."""
    return "-" if value is None else format(value, spec)


if __name__ == "__main__":
    main()
