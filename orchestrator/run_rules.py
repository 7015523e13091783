"""The rules a run applies to a checked scenario before it starts anything, whoever starts
it (the command line, the Python API or the pytest plugin): what this kind of run cannot
serve is refused as a ScenarioError naming the file and the fix, and what deserves a word
is returned as warnings (refused too in a strict run)."""

from __future__ import annotations

from orchestrator.proxies.foreign_launch import (
    PYTHON_GATE,
    gate_of,
    is_python,
    missing_program,
    rmw_gate_library,
)
from plan.errors import ScenarioError, ScenarioNotice
from plan.listen import address_problems, exposure_warnings
from plan.options import RunOptions
from plan.packing import packable
from plan.scenario import Scenario


def check_run(scenario: Scenario, options: RunOptions) -> list[str]:
    """Refuse what this run cannot serve; return the scenario's warnings (a strict run
    refuses the first of them) and the run's (a live endpoint reachable from other
    machines). An address the live view or rosbridge cannot listen on is a ValueError
    naming the option (the CLI's exit 2)."""
    foreign = [name for name, plan in scenario.nodes.items() if plan.foreign]
    if options.in_process and foreign:
        raise ScenarioError(scenario.file, "", "in-process runs step classes only; node(s) "
                            f"{', '.join(foreign)} are foreign programs (command:).",
                            "run without --in-process (in_process=False) for this scenario.")
    if scenario.model.transport == "zenoh" and foreign and not options.in_process:
        raise ScenarioError(scenario.file, "transport", "zenoh carries cosim nodes only; "
                            f"node(s) {', '.join(foreign)} are foreign ROS 2 programs "
                            "(command:) that talk DDS.", "transport: ros2 for this scenario.")
    _check_processes(scenario)
    for i, (name, plan) in enumerate(scenario.nodes.items()):
        if not plan.foreign:
            continue
        key = f"nodes[{i}] ({name}).command"
        problem = missing_program(plan, scenario.file.parent.resolve())
        if problem:
            raise ScenarioError(scenario.file, key, f"{problem}.", "a command that exists: "
                                "[python, path/to/program.py, ...] (paths relative to this "
                                "file) or a program on PATH.")
        fed_by = [inp for inp in plan.inputs if scenario.nodes[inp.producer].foreign]
        if fed_by:
            inp = fed_by[0]
            raise ScenarioError(
                scenario.file, f"nodes[{i}] ({name}).inputs", f"{inp.graph_topic} comes from "
                f"foreign program {inp.producer!r}: one foreign program feeding another is "
                "not covered (the orchestrator reads each foreign program's outputs once, to "
                "hash them, and cannot yet feed them on with their per-tick counts).",
                "a cosim node between them, or the two programs' work in one program.")
        if plan.params.gate == PYTHON_GATE and not is_python(plan):
            raise ScenarioError(
                scenario.file, f"nodes[{i}] ({name}).params.gate", f"{plan.spec.command[0]!r} "
                "is not a Python program, so the Python gate cannot serve it.",
                "gate: rmw (or auto) for a program on rcl in another language.")
        if gate_of(plan) is None and len(plan.inputs) > 1:
            raise ScenarioError(
                scenario.file, key, f"{plan.spec.command[0]!r} is not a Python program and "
                f"the RMW gate that serves other languages is not built ({rmw_gate_library()} "
                "is missing: it is x86-64 only), so its callbacks would see samples of "
                "different ticks from run to run (not deterministic).",
                "`make install` on x86-64, a Python (rclpy) program, or a program with one "
                "input.")
    if options.twin and scenario.model.twin is None:
        raise ScenarioError(scenario.file, "twin", f"--twin {options.twin}: the scenario has no "
                            "twin: section (the topic map)", "a twin: section, e.g. twin: "
                            "{subscribe: {/odom: /real/odom}} (see scenarios/twin.yaml)")
    problems = address_problems(options.live_address, options.rosbridge_address)
    if problems:
        raise ValueError("; ".join(problems))
    warnings = list(scenario.warnings)
    if options.strict and warnings:
        first = warnings[0]
        why = "refused by --strict (strict=True)" + (
            f"; {len(warnings) - 1} more warning(s)" if len(warnings) > 1 else "")
        if isinstance(first, ScenarioNotice):
            raise first.as_error(why)
        raise ScenarioError(scenario.file, "", f"{first} ({why})")
    return [*warnings, *exposure_warnings(options.live_address, options.rosbridge_address)]


def _check_processes(scenario: Scenario) -> None:
    """A ``process:`` name groups cosim nodes the orchestrator starts, with one prefix."""
    prefixes: dict[str, tuple[str, str | None]] = {}
    for i, (name, plan) in enumerate(scenario.nodes.items()):
        group = plan.spec.process
        if group is None:
            continue
        key = f"nodes[{i}] ({name}).process"
        if not packable(plan):
            raise ScenarioError(scenario.file, key, f"{name} is "
                                f"{'a foreign program' if plan.foreign else 'started by you'}"
                                "; only cosim nodes the orchestrator starts share a process.",
                                "leave process out for this node.")
        first = prefixes.setdefault(group, (name, plan.spec.prefix))
        if first[1] != plan.spec.prefix:
            raise ScenarioError(scenario.file, key, f"{name} and {first[0]} share process "
                                f"{group!r} but not their launch prefix.",
                                "the same prefix for every node of a process, or none.")
