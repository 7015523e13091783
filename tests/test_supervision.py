"""Fault injection with real processes: crashes, hangs, interrupts and orphans."""

from __future__ import annotations

import random
import signal
import subprocess
import time

import psutil
import pytest
import yaml
from rosbags.highlevel import AnyReader

from tests.helpers import ORCHESTRATE, ROOT, SCENARIOS, node_process, orchestrate

LONG = SCENARIOS / "long_chain.yaml"
HANG_S = 60  # generous: only a hang runs into it, however loaded the machine


class LiveRun:
    """cosim-orchestrate started in the background, with handles on its node processes."""

    def __init__(self, scenario, out):
        self.out = out
        self.proc = subprocess.Popen([*ORCHESTRATE, str(scenario),
                                      "--out", str(out)], cwd=ROOT, stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, text=True)
        self.ps = psutil.Process(self.proc.pid)

    def node(self, name: str) -> psutil.Process:
        """The process of node ``name``."""
        return node_process(self.proc.pid, name)

    def wait_running(self, min_bytes: int = 2000, timeout: float = 60) -> None:
        """Wait until ticks are being recorded."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            parts = list(self.out.glob("*/parts/tail.rec"))
            if parts and parts[0].stat().st_size > min_bytes:
                return
            assert self.proc.poll() is None, self.proc.communicate()
            time.sleep(0.05)
        raise TimeoutError("the run never got going")

    def finish(self, timeout: float = HANG_S) -> tuple[int, str, str]:
        """Wait for exit; (code, stdout, stderr)."""
        out, err = self.proc.communicate(timeout=timeout)
        return self.proc.returncode, out, err

    @property
    def run_dir(self):
        """The run directory."""
        return next(self.out.glob("*"))


def bag_counts(run_dir) -> dict[str, int]:
    """Messages per topic in the run's bag, read back and deserialised with rosbags."""
    counts: dict[str, int] = {}
    with AnyReader([run_dir / "bag"]) as reader:
        for conn, _, raw in reader.messages():
            reader.deserialize(raw, conn.msgtype)
            counts[conn.topic] = counts.get(conn.topic, 0) + 1
    return counts


def assert_nothing_left(pids: list[int]) -> None:
    """Every listed process is gone."""
    alive = [pid for pid in pids if psutil.pid_exists(pid)
             and psutil.Process(pid).status() != psutil.STATUS_ZOMBIE]
    assert not alive, f"still running: {alive}"


def test_kill_9_node_mid_run_stops_the_run_and_keeps_the_recording(tmp_path):
    run = LiveRun(LONG, tmp_path)
    run.wait_running()
    victim = run.node("middle")
    others = [c for c in run.ps.children() if c.pid != victim.pid]
    pids = [c.pid for c in run.ps.children()]
    victim.send_signal(signal.SIGKILL)
    _, alive = psutil.wait_procs(others, timeout=HANG_S)  # a hang guard, not a figure
    code, _, err = run.finish()  # then the bag, the picture and the manifest are written
    assert not alive
    assert code == 3
    assert "node middle died at tick" in err and "killed by signal SIGKILL" in err
    assert "Last lines of its log" in err
    assert_nothing_left(pids)
    counts = bag_counts(run.run_dir)
    assert counts["/head"] > 50 and counts["/middle"] > 50 and counts["/clock"] > 50


@pytest.mark.parametrize("transport", ["ros2", "zenoh"])
@pytest.mark.parametrize("mode,expect", [("kill", "killed by signal SIGKILL"),
                                         ("exit", "exit code 7")])
def test_node_dying_at_a_random_tick_is_named_with_the_tick(tmp_path, mode, expect, transport):
    tick = 2 * random.Random(f"{transport}-{mode}").randrange(3, 30)  # tail acts on even ticks
    doc = yaml.safe_load(LONG.read_text())
    doc["duration"] = "1s"
    doc["nodes"][2].update(kind="faulty", params={"output": "/tail", "fail_at": tick,
                                                  "mode": mode})
    path = tmp_path / "dies.yaml"
    path.write_text(yaml.safe_dump(doc))
    run = orchestrate(path, tmp_path / "out", "--transport", transport)
    assert run.code == 3
    assert f"node tail died at tick {tick} ({expect})" in run.stderr
    counts = bag_counts(run.run_dir)
    assert counts["/tail"] == tick // 2  # tail runs every other tick; ticks 0..tick-2 recorded


def test_stopped_node_misses_its_deadline_and_is_still_cleaned_up(tmp_path):
    run = LiveRun(LONG, tmp_path)
    run.wait_running()
    pids = [c.pid for c in run.ps.children()]
    run.node("tail").send_signal(signal.SIGSTOP)
    code, _, err = run.finish()
    assert code == 3
    assert "node tail did not finish tick" in err
    assert "process alive" in err and "stopped" in err
    assert "it needs /middle of tick" in err
    assert_nothing_left(pids)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_interrupting_the_orchestrator_exits_130_cleanly(tmp_path, sig):
    run = LiveRun(LONG, tmp_path)
    run.wait_running()
    children = run.ps.children()
    pids = [c.pid for c in children]
    run.proc.send_signal(sig)
    _, alive = psutil.wait_procs(children, timeout=HANG_S)
    code, _, err = run.finish()
    assert code == 130
    assert "Traceback" not in err
    assert not alive, f"nodes still running: {[p.pid for p in alive]}"
    assert_nothing_left(pids)
    manifest = yaml.safe_load((run.run_dir / "manifest.json").read_text())
    assert manifest["outcome"]["status"] == "interrupted"
    assert bag_counts(run.run_dir)["/tail"] > 10


def test_sigkill_to_the_orchestrator_leaves_no_orphan(tmp_path):
    run = LiveRun(LONG, tmp_path)
    run.wait_running()
    children = run.ps.children()
    run.proc.kill()
    run.proc.wait()
    gone, alive = psutil.wait_procs(children, timeout=5)
    assert not alive, f"orphans: {[p.pid for p in alive]}"
    assert len(gone) == 3


def test_node_failing_at_start_is_named_with_its_cause(tmp_path):
    doc = yaml.safe_load(LONG.read_text())
    doc["nodes"][1].update(kind="faulty", params={"output": "/middle", "mode": "setup"})
    path = tmp_path / "setup.yaml"
    path.write_text(yaml.safe_dump(doc))
    run = orchestrate(path, tmp_path / "out", timeout=HANG_S * 2)  # the hang guard
    assert run.code == 3
    assert "node middle died at start (exit code 1)" in run.stderr
    assert "RuntimeError: injected failure in setup" in run.stderr
