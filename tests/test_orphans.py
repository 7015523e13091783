"""No node outlives a SIGKILLed orchestrator, wherever the kill lands: at many points of
start-up and of the tick loop, and with a node that cannot act on the parent-death signal
(issue 40, item 5)."""

from __future__ import annotations

import os
import random
import subprocess
import time
import uuid

import psutil
import pytest
import yaml

from runtime.parent import GRACE_S
from tests.helpers import ORCHESTRATE, ROOT, SCENARIOS
from tests.test_supervision import RUN_MARK, carrying

LONG = SCENARIOS / "long_chain.yaml"
GONE_S = GRACE_S + 15  # the watchdog's grace, and a loaded machine's slowness


def _start(scenario, out, *args: str, mark: str) -> subprocess.Popen:
    return subprocess.Popen([*ORCHESTRATE, str(scenario), "--out", str(out), "--quiet",
                             "--no-picture", *args],
                            cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            env={**os.environ, RUN_MARK: mark})


def _kill_and_expect_nothing_left(proc: subprocess.Popen, mark: str) -> float:
    """SIGKILL the orchestrator; seconds until no process of its run is left (fails after
    GONE_S)."""
    proc.kill()
    proc.wait()
    killed = time.monotonic()
    while (left := carrying(mark)) and time.monotonic() - killed < GONE_S:
        time.sleep(0.05)
    assert not left, f"orphans: {[(p.pid, p.name(), p.status()) for p in left]}"
    return time.monotonic() - killed


@pytest.mark.parametrize("spawn", ["fork", "exec"])
def test_sigkill_at_many_points_of_start_up_and_tick_loop_leaves_nothing(tmp_path, spawn):
    rng = random.Random(f"orphans-{spawn}")
    # start-up: the forks, the arming of each child's parent-death signal, discovery;
    # then the tick loop (long_chain records from about 1-2 s on)
    delays = sorted([rng.uniform(0.0, 0.6) for _ in range(4)]
                    + [rng.uniform(0.6, 2.5) for _ in range(3)] + [rng.uniform(2.5, 5.0)])
    for i, delay in enumerate(delays):
        mark = uuid.uuid4().hex
        proc = _start(LONG, tmp_path / f"r{i}", "--spawn", spawn, mark=mark)
        time.sleep(delay)
        _kill_and_expect_nothing_left(proc, mark)


def test_a_node_that_cannot_act_on_its_parents_death_is_still_gone(tmp_path):
    doc = yaml.safe_load(LONG.read_text())
    doc["nodes"][0].update(kind="faulty", params={"output": "/head", "fail_at": 20,
                                                  "mode": "deaf"})
    doc["deadlines"] = {"start": "30s", "tick": "60s"}  # the orchestrator waits on head
    path = tmp_path / "deaf.yaml"
    path.write_text(yaml.safe_dump(doc))
    mark = uuid.uuid4().hex
    proc = _start(path, tmp_path / "out", mark=mark)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:  # until head hangs at tick 20 with signals ignored
        heads = [p for p in carrying(mark) if p.name() == "cosim:head"]
        if heads and list((tmp_path / "out").glob("*/parts/tail.rec")):
            break
        time.sleep(0.1)
    time.sleep(1.0)
    (head,) = [p for p in carrying(mark) if p.name() == "cosim:head"]
    seconds = _kill_and_expect_nothing_left(proc, mark)
    assert seconds >= GRACE_S * 0.8  # it went by the watchdog's SIGKILL, after the grace
    assert not psutil.pid_exists(head.pid) or head.status() == psutil.STATUS_ZOMBIE
