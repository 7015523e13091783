"""Real ROS 2 programs with several inputs stay bit-identical in lockstep (the delivery
contract in the README): plain rclpy programs of the tests' own, whatever the order they
create their subscriptions in, their executor, or a sim-time timer, get every tick's inputs
as one whole. Three runs (two with the processes started in a shuffled order) and one with
every core busy give one digest, and every output is the function of the very samples the
schedule names."""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import time

import pytest
import yaml

from orchestrator.outputs.bag import BagReader
from tests.helpers import SCENARIOS, orchestrate

FUSION = SCENARIOS / "foreign_fusion.yaml"
# the publishing callback (b's) last: callbacks run in the order of the declared inputs
THREE = [{"topic": "/a", "mode": "same_tick"}, {"topic": "/c", "mode": "same_tick"},
         {"topic": "/b", "mode": "same_tick"}]


def variant(tmp_path, args: list[str], *, inputs=None, rate=20, timer=False):
    """The fusion scenario with the program's parameters, inputs and rate changed."""
    doc = yaml.safe_load(FUSION.read_text())
    program = doc["nodes"][3]
    program["command"] = ["python", str(SCENARIOS.parent / "programs" / "fusion.py"),
                          "--ros-args", *[a for p in args for a in ("-p", p)]]
    program["rate"] = rate
    if inputs:
        program["inputs"] = inputs
    if timer:  # the timer publishes from one period in; nothing may consume its output
        program["params"]["silent_at_start"] = True
        doc["nodes"].pop(4)
    path = tmp_path / "fusion.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def _spin(seconds: float) -> None:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        pass


@contextlib.contextmanager
def every_core_busy(seconds: float = 120):
    """One busy spinner per core this process may run on, for the block (then killed)."""
    procs = [multiprocessing.Process(target=_spin, args=(seconds,), daemon=True)
             for _ in range(len(os.sched_getaffinity(0)))]
    for p in procs:
        p.start()
    try:
        yield
    finally:
        for p in procs:
            p.kill()
            p.join()


def by_tick(run_dir, tick_ns: int) -> dict[str, dict[int, int]]:
    """topic -> tick -> Int64 value, from the bag."""
    out: dict[str, dict[int, int]] = {}
    with BagReader(run_dir / "bag") as bag:
        for topic in ("/a", "/b", "/c", "/out"):
            if topic in bag.counts:
                out[topic] = {stamp // tick_ns: msg.data for stamp, msg in bag.messages(topic)}
    return out


CASES = {
    "subscriptions a then b": (["inputs:=2", "order:=abc"], None, 20, False),
    "subscriptions b then a": (["inputs:=2", "order:=cba"], None, 20, False),
    # a's callback takes 30 ms and may overlap b's (a reentrant group, four threads): only
    # the gate, waiting for a's to finish, makes b's output see a's sample of the same tick
    "multi-threaded executor": (["inputs:=2", "executor:=multi", "reentrant:=true",
                                 "slow:=a", "work_ms:=30"], None, 20, False),
    "10 Hz sim-time timer": (["inputs:=2", "trigger:=timer"], None, 10, True),
    "three inputs": (["inputs:=3", "order:=cba"], THREE, 20, False),
}


@pytest.mark.parametrize("case", list(CASES))
def test_several_inputs_give_one_digest_every_run(tmp_path, case):
    args, inputs, rate, timer = CASES[case]
    path = variant(tmp_path, args, inputs=inputs, rate=rate, timer=timer)
    runs = [orchestrate(path, tmp_path / "run0"),
            *(orchestrate(path, tmp_path / f"run{n}", "--shuffle-start", str(n))
              for n in (1, 2))]
    with every_core_busy():
        runs.append(orchestrate(path, tmp_path / "loaded", "--shuffle-start", "3"))
    for run in runs:
        assert run.code == 0, run.stderr
    digests = {run.manifest["digest"] for run in runs}
    assert len(digests) == 1, digests
    tick_ns = runs[0].manifest["tick_ns"]
    values = by_tick(runs[0].run_dir, tick_ns)
    period = 100 // rate
    fed = [t for t in sorted(values["/a"]) if t % period == 0]
    names = "abc"[:3 if inputs else 2]
    for tick in fed[1 if timer else 0:]:
        # the program's output of a tick is the function of that tick's samples
        samples = [values[f"/{n}"][max(t for t in values[f"/{n}"] if t <= tick)] for n in names]
        expected = sum(v * 1000 ** (2 - i) for i, v in enumerate(samples))
        assert values["/out"][tick] == expected, (case, tick, samples)
