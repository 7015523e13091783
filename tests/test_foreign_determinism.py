"""Real ROS 2 programs with several inputs stay bit-identical in lockstep (the delivery
contract, docs/how-to/foreign-programs.md): plain rclpy programs of the tests' own,
whatever the order they
create their subscriptions in, their executor, a sim-time timer, best-effort subscriptions,
or how many messages they publish per tick (none on some, two on others), get every tick's
inputs as one whole. Runs (all but the first with the processes started in a shuffled
order), one with every core busy, give one digest; every output is the function of the very
samples the schedule names; and the sink consuming the program's output sees, at each tick,
the latest message published before it (none before the first)."""

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


def variant(tmp_path, args: list[str], *, inputs=None, rate=20, params=None):
    """The fusion scenario with the program's parameters, inputs and rate changed."""
    doc = yaml.safe_load(FUSION.read_text())
    program = doc["nodes"][3]
    program["command"] = ["python", str(SCENARIOS.parent / "programs" / "fusion.py"),
                          "--ros-args", *[a for p in args for a in ("-p", p)]]
    program["rate"] = rate
    program["params"].update(params or {})
    if inputs:
        program["inputs"] = inputs
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


def by_tick(run_dir, tick_ns: int) -> dict[str, dict[int, list[int]]]:
    """topic -> tick -> the Int64 values published at that tick, in order, from the bag."""
    out: dict[str, dict[int, list[int]]] = {}
    with BagReader(run_dir / "bag") as bag:
        for topic in ("/a", "/b", "/c", "/out", "/sink"):
            if topic in bag.counts:
                out[topic] = {}
                for stamp, msg in bag.messages(topic):
                    out[topic].setdefault(stamp // tick_ns, []).append(msg.data)
    return out


# case: (program parameters, inputs, rate). Each case runs twice: a plain start, then a
# start in a shuffled order with every core busy (the second run is both the independent
# repeat and the adverse one; the schedule is checked tick by tick against the first)
CASES = {
    "subscriptions a then b": (["inputs:=2", "order:=abc"], None, 20),
    "subscriptions b then a": (["inputs:=2", "order:=cba"], None, 20),
    # a's callback takes 30 ms and may overlap b's (a reentrant group, four threads): only
    # the gate, waiting for a's to finish, makes b's output see a's sample of the same tick
    "multi-threaded executor": (["inputs:=2", "executor:=multi", "reentrant:=true",
                                 "slow:=a", "work_ms:=30"], None, 20),
    "10 Hz sim-time timer": (["inputs:=2", "trigger:=timer"], None, 10),
    "three inputs": (["inputs:=3", "order:=cba"], THREE, 20),
    "publishes on some ticks only": (["inputs:=2", "when:=even"], None, 20),
    "publishes twice in one tick": (["inputs:=2", "copies:=2"], None, 20),
    "best-effort subscriptions": (["inputs:=2", "qos:=sensor"], None, 20),
}


def expected_out(args: list[str], tick: int, samples: list[int]) -> list[int]:
    """What fusion.py publishes at a fed tick, given the samples it holds then."""
    if "trigger:=timer" in args and tick == 0:
        return []  # a timer first fires one period after its creation
    value = sum(v * 1000 ** (2 - i) for i, v in enumerate(samples))
    if "when:=even" in args and sum(samples) % 2:
        return []
    return [value, value + 1] if "copies:=2" in args else [value]


def expected_sink(tick: int, out: dict[int, list[int]]) -> int:
    """The counter 'sink' (rate 100, /out delayed): the latest /out message published before
    ``tick``, none yet before the first (then it adds nothing)."""
    value = (tick + 1) * 1000 + tick
    before = [t for t in out if t < tick and out[t]]
    if before:
        value = (value * 31 + out[max(before)][-1]) % (1 << 62)
    return value


@pytest.mark.parametrize("case", list(CASES))
def test_several_inputs_give_one_digest_every_run(tmp_path, case):
    args, inputs, rate = CASES[case]
    path = variant(tmp_path, args, inputs=inputs, rate=rate)
    runs = [orchestrate(path, tmp_path / "run0")]
    with every_core_busy():
        runs.append(orchestrate(path, tmp_path / "loaded", "--shuffle-start", "1"))
    for run in runs:
        assert run.code == 0, run.stderr
    digests = {run.manifest["digest"] for run in runs}
    assert len(digests) == 1, digests
    tick_ns = runs[0].manifest["tick_ns"]
    values = by_tick(runs[0].run_dir, tick_ns)
    out = values.get("/out", {})
    period = 100 // rate
    fed = [t for t in sorted(values["/a"]) if t % period == 0]
    names = "abc"[:3 if inputs else 2]
    for tick in fed:
        # the program's output of a tick is the function of that tick's samples
        samples = [values[f"/{n}"][max(t for t in values[f"/{n}"] if t <= tick)][0]
                   for n in names]
        assert out.get(tick, []) == expected_out(args, tick, samples), (case, tick, samples)
    for tick, (sink,) in values["/sink"].items():
        assert sink == expected_sink(tick, out), (case, tick)
    if "when:=even" in args:  # the rule at work: silent ticks, and ticks of held samples
        assert 0 < len([t for t in fed if out.get(t)]) < len(fed)
    assert runs[0].manifest["foreign"]["fusion"]["gated"]


def test_a_declared_count_is_checked(tmp_path):
    """Where the scenario declares an exact count, another count is an error naming it."""
    path = variant(tmp_path, ["inputs:=2", "copies:=2"],
                   params={"per_activation": {"/out": 1}})
    done = orchestrate(path, tmp_path / "r")
    assert done.code == 3, done.stderr
    assert "published 2 message(s) on /out at tick 0" in done.stderr
    assert "params.per_activation./out" in done.stderr


def test_a_program_on_the_wall_clock_is_named(tmp_path):
    """A program that sets use_sim_time to false is stopped with an error, not run on the
    wall clock."""
    done = orchestrate(variant(tmp_path, ["inputs:=2", "wall_clock:=true"]), tmp_path / "r")
    assert done.code == 3, done.stderr
    assert "runs with use_sim_time false" in done.stderr and "'fusion'" in done.stderr
