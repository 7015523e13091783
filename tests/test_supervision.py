"""Fault injection with real processes: crashes, hangs, interrupts and orphans."""

from __future__ import annotations

import os
import random
import signal
import subprocess
import time
import uuid

import psutil
import pytest
import yaml
from rosbags.highlevel import AnyReader

from tests.helpers import ORCHESTRATE, ROOT, SCENARIOS, node_process, orchestrate

LONG = SCENARIOS / "long_chain.yaml"
HANG_S = 60  # generous: only a hang runs into it, however loaded the machine


class LiveRun:
    """cosim-orchestrate started in the background, with handles on its node processes."""

    def __init__(self, scenario, out, *args: str, env: dict[str, str] | None = None,
                 preexec_fn=None):
        self.out = out
        self.proc = subprocess.Popen([*ORCHESTRATE, str(scenario), "--out", str(out),
                                      "--no-picture", *args],
                                     cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     text=True, env={**os.environ, **(env or {})},
                                     preexec_fn=preexec_fn)
        self.ps = psutil.Process(self.proc.pid)

    def node(self, name: str) -> psutil.Process:
        """The process of node ``name``."""
        return node_process(self.proc.pid, name)

    def wait_running(self, min_bytes: int = 2000, timeout: float = 60,
                     part: str = "tail") -> None:
        """Wait until ticks are being recorded (node ``part``'s)."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            parts = list(self.out.glob(f"*/parts/{part}.rec"))
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


def test_a_run_started_with_ctrl_c_ignored_or_blocked_is_still_interrupted(tmp_path):
    """A script's background job starts with SIGINT ignored, a test worker may pass a mask on:
    exit 130 on SIGINT is the command's contract all the same."""
    def deaf_to_ctrl_c():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGTERM})

    run = LiveRun(LONG, tmp_path, preexec_fn=deaf_to_ctrl_c)
    try:
        run.wait_running()
        run.proc.send_signal(signal.SIGINT)
        code, _, err = run.finish()
    finally:
        run.proc.kill()
    assert code == 130, err


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


RUN_MARK = "COSIM_TEST_RUN"  # set for one orchestrator: every process of its run carries it
ORPHAN_CASES = {  # scenario, options, the node whose recording shows the run going
    "forked nodes": (LONG, (), "tail"),
    "--spawn exec": (LONG, ("--spawn", "exec"), "tail"),
    "packed process": (LONG, ("--pack", "kind"), "tail"),
    "zenoh": (LONG, ("--transport", "zenoh"), "tail"),
    "foreign program": (SCENARIOS / "foreign_echo.yaml", ("--duration", "120s"), "sink"),
}


def carrying(mark: str) -> list[psutil.Process]:
    """Live processes whose environment has RUN_MARK=mark (forked ones show the
    orchestrator's environment, programs it started inherit it)."""
    found = []
    for proc in psutil.process_iter():
        try:
            if proc.environ().get(RUN_MARK) == mark and proc.status() != psutil.STATUS_ZOMBIE:
                found.append(proc)
        except (psutil.Error, OSError):
            continue
    return found


@pytest.mark.parametrize("case", list(ORPHAN_CASES))
def test_sigkill_to_the_orchestrator_leaves_no_process_of_any_kind(tmp_path, case):
    scenario, args, part = ORPHAN_CASES[case]
    mark = uuid.uuid4().hex
    run = LiveRun(scenario, tmp_path, *args, env={RUN_MARK: mark})
    run.wait_running(part=part)
    started = {p.pid for p in carrying(mark)}
    tree = {p.pid for p in run.ps.children(recursive=True)}
    assert run.proc.pid in started and tree and tree <= started  # the mark sees them all
    run.proc.kill()
    run.proc.communicate()
    deadline = time.monotonic() + HANG_S  # a hang guard: they go at once, or never
    while (left := carrying(mark)) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not left, f"orphans: {[(p.pid, p.name()) for p in left]}"


def test_node_failing_at_start_is_named_with_its_cause(tmp_path):
    doc = yaml.safe_load(LONG.read_text())
    doc["nodes"][1].update(kind="faulty", params={"output": "/middle", "mode": "setup"})
    path = tmp_path / "setup.yaml"
    path.write_text(yaml.safe_dump(doc))
    run = orchestrate(path, tmp_path / "out", timeout=HANG_S * 2)  # the hang guard
    assert run.code == 3
    assert "node middle died at start (exit code 1)" in run.stderr
    assert "RuntimeError: injected failure in setup" in run.stderr
