"""How a foreign program is started (kept apart from ``orchestrator.proxies.foreign_proxy``, which
loads rclpy: the orchestrator builds the command before it forks its own node processes).

A program a gate serves is *gated* (every program, where ``make install`` built the RMW
gate): its inputs and its ``/clock`` are remapped onto private feed topics
that the orchestrator alone publishes, one tick's bundle at a time, and a gate holds the
program's executor until a whole bundle is in its readers (the delivery contract,
docs/how-to/foreign-programs.md), and acknowledges each tick with how many messages it
published on each output, so the program may publish zero, one or several per tick. Two
gates keep that one contract (``NodePlan.gate``, ``plan.gates``):

- ``python``: for a Python program (its command runs ``python``/``python3`` or a ``.py``
  file), ``runtime/foreign_gate`` injected through ``sitecustomize`` on its ``PYTHONPATH``;
- ``rmw``: for any program on rcl (C, C++, Python), ``librmw_cosim_gate.so``
  (``runtime/rmw_gate``, built by ``make install``), preloaded with
  ``RMW_IMPLEMENTATION=rmw_cosim_gate`` and configured by ``COSIM_RMW_GATE`` (which names
  the outputs it counts, in the same order as the Python gate's configuration).

``params.gate`` picks one (``auto``: python for a Python program, rmw for any other). Without
the RMW library (not built: not x86-64) a program that is not Python is ungated and reads
the run's topics directly: deterministic only with a single input and a fixed message count,
so the run rules refuse it with more inputs and plan.checks holds it to its counts.
"""

from __future__ import annotations

import json
import os
import shutil
import sys
from pathlib import Path

from plan.gates import (
    PYTHON_GATE,
    PYTHONS,
    RMW_GATE_NAME,
    ack_topic,
    feed_prefix,
    is_python_command,
    rmw_gate_library,
)
from plan.packing import ProcessLayout
from plan.robots import robot_of
from plan.scenario import NodePlan, Scenario
from plan.schedule import DELAYED, Schedule
from plan.timeutil import tick_text

__all__ = ["ack_topic", "clock_topic", "feed_prefix", "feed_topic", "foreign_argv",
           "foreign_env", "gate_config", "gate_of", "is_python", "missing_program",
           "rmw_gate_library", "rmw_gate_text"]

GATE_DIR = Path(__file__).resolve().parents[2] / "runtime" / "foreign_gate"
GATE_ENV = "COSIM_GATE"
RMW_GATE_ENV = "COSIM_RMW_GATE"


def feed_topic(name: str, own_topic: str) -> str:
    """Where the program's input ``own_topic`` (its own name, e.g. /scan) is fed."""
    return feed_prefix(name) + own_topic.lstrip("/")


def clock_topic(name: str) -> str:
    """The program's /clock, fed with the ticks it is due at."""
    return feed_prefix(name) + "clock"


def is_python(plan: NodePlan) -> bool:
    """Whether the program runs on a Python interpreter (and so can carry the Python gate)."""
    return is_python_command(plan.spec.command)


def gate_of(plan: NodePlan) -> str | None:
    """Which gate serves the program: 'python', 'rmw', or None (ungated: the RMW gate is
    not built). The same as ``plan.gate``."""
    return plan.gate


def missing_program(plan: NodePlan, scenario_dir: Path) -> str | None:
    """Why the program's command cannot start (its executable or script is not there), or
    None."""
    argv = plan.spec.command
    first = argv[0]
    if first in PYTHONS:
        script = next((a for a in argv[1:] if not a.startswith("-")), None)
        if script and script.endswith(".py") and not (scenario_dir / script).is_file():
            return f"the script {script!r} does not exist (looked for {scenario_dir / script})"
        return None
    if "/" in first:
        path = scenario_dir / first
        if not path.is_file():
            return f"{first!r} does not exist (looked for {path})"
        if not os.access(path, os.X_OK):
            return f"{first!r} is not executable ({path})"
        return None
    if shutil.which(first) is None:
        return f"no program {first!r} on PATH"
    return None


def gate_config(plan: NodePlan, schedule: Schedule, readers: list[int] | None = None) -> dict:
    """The gate's configuration: the feed prefix, the program's period, per input the ticks
    its sample comes with (a delayed input has none at tick 0), the outputs it counts in
    each acknowledgement, and (``readers``, see ``output_readers``) how many subscriptions
    each output's publisher must match before the gate tells the orchestrator so."""
    period = plan.period_ticks
    inputs = []
    for inp, edge in zip(plan.inputs, schedule.inputs_of[plan.name], strict=True):
        entry = {"topic": inp.topic.lstrip("/")}
        if edge.mode == DELAYED:
            entry["first"] = period  # the first activation with an earlier sample
        inputs.append(entry)
    return {"prefix": feed_prefix(plan.name), "node": plan.name,
            "tick_ns": tick_text(schedule.tick_ns), "period": period, "start": 0,
            "inputs": inputs, "reliable_clock": True,
            "callback_order": "inputs", "outputs": plan.gated_outputs,
            **({"readers": readers} if readers else {})}


def output_readers(scenario: Scenario, layout: ProcessLayout, plan: NodePlan
                   ) -> list[int] | None:
    """Per gated output of a foreign program, the subscriptions it will match: one per
    process with a consumer of it (the run's ``layout``) and the orchestrator's
    own. None where a consumer runs in the orchestrator (its readers are not told apart
    there): the orchestrator then waits a settle time instead."""
    consumers = {e.consumer for e in scenario.schedule.edges if e.producer == plan.name}
    if any(scenario.nodes[c].role.stood_in for c in consumers):
        return None
    counts = layout.subscribers(plan.name)
    return [counts.get(topic, 0) + 1 for topic in plan.gated_outputs]


def foreign_argv(plan: NodePlan, scenario_dir: Path) -> list[str]:
    """The program's command line: 'python' means this interpreter; use_sim_time and the
    remaps (the scenario's, and for a gated program its inputs and /clock onto the feed)
    are appended as a ROS arguments block of their own."""
    argv = list(plan.spec.command)
    if argv[0] in PYTHONS:
        argv[0] = sys.executable
    argv += ["--ros-args", "-p", "use_sim_time:=true"]
    gated = gate_of(plan) is not None
    fed = {inp.topic for inp in plan.inputs} if gated else set()
    # a robot's copy runs in the robot's namespace (__ns:=/ROBOT): its own topics are
    # matched as the relative names they are there ('in' is /robot_3/in)
    rule = (lambda own: own.lstrip("/")) if robot_of(plan.name) else (lambda own: own)
    for own, graph in plan.spec.remap.items():
        if own not in fed:
            argv += ["-r", f"{rule(own)}:={graph}"]
    for own in sorted(fed):
        argv += ["-r", f"{rule(own)}:={feed_topic(plan.name, own)}"]
    if gated:
        argv += ["-r", f"/clock:={clock_topic(plan.name)}"]
    return argv


def rmw_gate_text(config: dict) -> str:
    """The RMW gate's configuration (``COSIM_RMW_GATE``, one item a line) from the gate
    configuration both gates share."""
    lines = [f"prefix {config['prefix']}", f"node {config['node']}",
             f"period {config['period']}", f"start {config['start']}"]
    for entry in config["inputs"]:
        lines.append(f"input {entry['topic']} {entry.get('period', config['period'])} "
                     f"{entry.get('phase', config['start'])} {entry.get('first', 0)}")
    # the outputs it counts per acknowledgement, in this order (resolved topic names)
    lines += [f"output {topic}" for topic in config["outputs"]]
    return "\n".join(lines) + "\n"


def foreign_env(plan: NodePlan, schedule: Schedule,
                readers: list[int] | None = None) -> dict[str, str] | None:
    """The environment of a gated program (its gate and the gate's configuration, with
    ``readers`` for the Python gate), or None for an ungated one (it inherits the
    orchestrator's)."""
    gate = gate_of(plan)
    if gate is None:
        return None
    env = dict(os.environ)
    config = gate_config(plan, schedule, readers)
    if gate == PYTHON_GATE:
        env["PYTHONPATH"] = os.pathsep.join(
            [str(GATE_DIR), *filter(None, [env.get("PYTHONPATH")])])
        env[GATE_ENV] = json.dumps(config)
        return env
    # The wheels' librcl links librmw_fastrtps_cpp itself (no rmw_implementation loader):
    # preloading the gate puts its rmw_* definitions first; RMW_IMPLEMENTATION makes rcl
    # refuse to start if the preload did not take.
    env["LD_PRELOAD"] = " ".join([str(rmw_gate_library()),
                                  *filter(None, [env.get("LD_PRELOAD")])])
    env["RMW_IMPLEMENTATION"] = RMW_GATE_NAME
    env[RMW_GATE_ENV] = rmw_gate_text(config)
    env.pop(GATE_ENV, None)
    return env
