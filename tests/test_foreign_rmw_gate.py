"""Programs that are not Python get the same delivery contract through the RMW gate
(librmw_cosim_gate.so, built by `make install`): a plain C program on rcl with two inputs
(tests/programs/fusion_c.c) gives one digest over three runs and one with both cores busy,
every output is the function of the very samples the schedule names, from a sim-time
timer (nothing at tick 0) or from an input callback, whatever order its wait set lists its
inputs in, and the sink consuming its output sees the latest message published before its
tick (none yet before the first): the gate acknowledges each tick with its per-output
counts, as the Python gate does. An rclpy program run through the RMW gate instead of the
Python gate gives the Python gate's digest, also when it publishes on some ticks only or
twice in one tick."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
import yaml

from tests.helpers import SCENARIOS, orchestrate
from tests.test_foreign_determinism import by_tick, every_core_busy, expected_sink, variant
from tests.test_foreign_nav import nav_with_foreign_control

FUSION_C = Path(sys.prefix) / "cosim_native" / "bin" / "fusion_c"


def c_variant(tmp_path, order: str, trigger: str):
    """The fusion scenario with the C program: two inputs, at 10 Hz on its timer (it
    publishes nothing at tick 0: its sink sees none yet) or at 20 Hz from b's callback."""
    doc = yaml.safe_load((SCENARIOS / "foreign_fusion.yaml").read_text())
    program = doc["nodes"][3]
    program["command"] = [str(FUSION_C), order, trigger]
    if trigger == "timer":
        program["rate"] = 10
    path = tmp_path / f"fusion_c_{order}_{trigger}.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def assert_outputs_follow_the_schedule(run, rate: int, timer: bool) -> None:
    values = by_tick(run.run_dir, run.manifest["tick_ns"])
    out = values["/out"]
    period = 100 // rate
    fed = [t for t in sorted(values["/a"]) if t % period == 0]
    assert len(fed) > 5
    for tick in fed:
        samples = [values[n][max(t for t in values[n] if t <= tick)][0] for n in ("/a", "/b")]
        want = [] if timer and tick == 0 else [samples[0] * 1000 + samples[1]]
        assert out.get(tick, []) == want, (tick, samples)
    for tick, (sink,) in values["/sink"].items():
        assert sink == expected_sink(tick, out), tick
    assert run.manifest["foreign"]["fusion"]["gate"] == "rmw"


@pytest.mark.parametrize(("order", "trigger", "quiet_runs"), [("ab", "timer", 2), ("ba", "b", 1)])
def test_a_c_program_with_two_inputs_gives_one_digest_every_run(tmp_path, order, trigger,
                                                                 quiet_runs):
    assert FUSION_C.is_file(), "make install builds tests/programs/fusion_c.c"
    path = c_variant(tmp_path, order, trigger)
    runs = [orchestrate(path, tmp_path / f"run{n}") for n in range(quiet_runs)]
    with every_core_busy():
        runs.append(orchestrate(path, tmp_path / "loaded"))
    for run in runs:
        assert run.code == 0, run.stderr
    assert len({run.manifest["digest"] for run in runs}) == 1
    timer = trigger == "timer"
    assert_outputs_follow_the_schedule(runs[0], 10 if timer else 20, timer)


@pytest.mark.parametrize("case", [(["inputs:=2", "order:=cba"], 20),
                                  (["inputs:=2", "trigger:=timer"], 10),
                                  (["inputs:=2", "when:=even"], 20),
                                  (["inputs:=2", "copies:=2"], 20)],
                         ids=["subscriptions b then a", "10 Hz sim-time timer",
                              "publishes on some ticks only", "publishes twice in one tick"])
def test_an_rclpy_program_through_the_rmw_gate_gives_the_python_gates_digest(tmp_path, case):
    args, rate = case
    python = variant(tmp_path, args, rate=rate)
    doc = yaml.safe_load(python.read_text())
    doc["nodes"][3]["params"]["gate"] = "rmw"
    rmw = tmp_path / "fusion_rmw.yaml"
    rmw.write_text(yaml.safe_dump(doc))
    ours = orchestrate(python, tmp_path / "python")
    theirs = orchestrate(rmw, tmp_path / "rmw")
    assert ours.code == 0, ours.stderr
    assert theirs.code == 0, theirs.stderr
    assert theirs.manifest["digest"] == ours.manifest["digest"]
    # the digest covers the sink too, which reads the gate's per-tick counts
    assert by_tick(theirs.run_dir, theirs.manifest["tick_ns"])["/sink"]


def test_the_nav_controller_through_the_rmw_gate_gives_the_builtin_digest(tmp_path):
    builtin, foreign = nav_with_foreign_control(tmp_path)
    doc = yaml.safe_load(foreign.read_text())
    next(n for n in doc["nodes"] if n["name"] == "control")["params"]["gate"] = "rmw"
    foreign.write_text(yaml.safe_dump(doc))
    ours = orchestrate(builtin, tmp_path / "a", "--in-process")
    theirs = orchestrate(foreign, tmp_path / "b")
    assert ours.code == theirs.code == 1, theirs.stderr  # 3 s: the goal is not reached yet
    assert theirs.manifest["digest"] == ours.manifest["digest"]


def test_an_executor_the_rmw_gate_cannot_serve_is_named(tmp_path):
    # rclpy's MultiThreadedExecutor takes in worker threads: nothing at the RMW layer says
    # when their callbacks end (the Python gate serves it)
    path = variant(tmp_path, ["inputs:=2", "executor:=multi"])
    doc = yaml.safe_load(path.read_text())
    doc["nodes"][3]["params"]["gate"] = "rmw"
    path.write_text(yaml.safe_dump(doc))
    done = orchestrate(path, tmp_path / "r")
    assert done.code == 3, done.stderr
    assert "node fusion died" in done.stderr, done.stderr
    assert "MultiThreadedExecutor" in done.stderr and "params.gate: python" in done.stderr


def test_the_rmw_gate_defines_every_function_of_the_middleware_it_wraps():
    # what rcl (or a ROS install's rmw_implementation loader) may call must all be there:
    # the gated ones, and a forwarding stub for every other
    from tools.build_native import REAL_LIBRARY, defined_rmw_functions, gate_library

    real = defined_rmw_functions(Path(sys.prefix) / "lib" / REAL_LIBRARY)
    assert len(real) > 50
    assert set(defined_rmw_functions(gate_library().resolve())) == set(real)
