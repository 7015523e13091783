"""The rules a run applies to a checked scenario before it starts anything, whoever starts
it (the command line, the Python API or the pytest plugin): what this kind of run cannot
serve is refused as a ScenarioError naming the file and the fix, and what deserves a word
is returned as warnings (refused too in a strict run).

Each rule is a named check (``RULES``, applied in order; the first refusal stops the run):
a function of the scenario and the run options that raises to refuse and returns the
warnings it has. The rules about one foreign program (``FOREIGN_RULES``) are applied to each
foreign program in turn, in the scenario's order.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

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
from plan.scenario import NodePlan, Scenario


@dataclass(frozen=True)
class Rule:
    """A named rule of a run: ``check(scenario, options)`` raises to refuse the run and
    returns its warnings. ``doc`` says what it holds."""

    name: str
    check: Callable[[Scenario, RunOptions], list]

    @property
    def doc(self) -> str:
        """The rule's docstring."""
        return self.check.__doc__ or ""


@dataclass(frozen=True)
class ForeignRule:
    """A named rule about one foreign program of the scenario: ``check(scenario, index,
    name, plan)`` raises to refuse the run."""

    name: str
    check: Callable[[Scenario, int, str, NodePlan], None]

    @property
    def doc(self) -> str:
        """The rule's docstring."""
        return self.check.__doc__ or ""


RULES: list[Rule] = []
"""The run's rules, in the order they are applied."""
FOREIGN_RULES: list[ForeignRule] = []
"""The rules each foreign program is held to, in the order they are applied."""


def rule(check: Callable[[Scenario, RunOptions], list]) -> Callable[[Scenario, RunOptions], list]:
    """Register ``check`` as a rule of every run, named after the function."""
    RULES.append(Rule(check.__name__, check))
    return check


def foreign_rule(check: Callable[[Scenario, int, str, NodePlan], None]
                 ) -> Callable[[Scenario, int, str, NodePlan], None]:
    """Register ``check`` as a rule about each foreign program, named after the function."""
    FOREIGN_RULES.append(ForeignRule(check.__name__, check))
    return check


def check_run(scenario: Scenario, options: RunOptions) -> list[str]:
    """Refuse what this run cannot serve; return the scenario's warnings (a strict run
    refuses the first of them) and the run's (a live endpoint reachable from other
    machines). An address the live view or rosbridge cannot listen on is a ValueError
    naming the option (the CLI's exit 2)."""
    warnings: list[str] = []
    for each in RULES:
        warnings += each.check(scenario, options)
    return warnings


def _foreign(scenario: Scenario) -> list[str]:
    """The names of the scenario's foreign programs (``command:``)."""
    return [name for name, plan in scenario.nodes.items() if plan.role.is_foreign]


@rule
def in_process_runs_step_classes(scenario: Scenario, options: RunOptions) -> list:
    """An in-process run steps classes only: no foreign program (``command:``)."""
    foreign = _foreign(scenario)
    if options.in_process and foreign:
        raise ScenarioError(scenario.file, "", "in-process runs step classes only; node(s) "
                            f"{', '.join(foreign)} are foreign programs (command:).",
                            "run without --in-process (in_process=False) for this scenario.")
    return []


@rule
def zenoh_carries_cosim_nodes(scenario: Scenario, options: RunOptions) -> list:
    """Over zenoh only cosim nodes talk: a foreign ROS 2 program speaks DDS."""
    foreign = _foreign(scenario)
    if scenario.model.transport == "zenoh" and foreign and not options.in_process:
        raise ScenarioError(scenario.file, "transport", "zenoh carries cosim nodes only; "
                            f"node(s) {', '.join(foreign)} are foreign ROS 2 programs "
                            "(command:) that talk DDS.", "transport: ros2 for this scenario.")
    return []


@rule
def process_groups(scenario: Scenario, options: RunOptions) -> list:
    """A ``process:`` name groups cosim nodes the orchestrator starts, with one prefix."""
    prefixes: dict[str, tuple[str, str | None]] = {}
    for i, (name, plan) in enumerate(scenario.nodes.items()):
        group = plan.spec.process
        if group is None:
            continue
        key = f"nodes[{i}] ({name}).process"
        if not plan.role.packable:
            what = "a foreign program" if plan.role.is_foreign else "started by you"
            raise ScenarioError(scenario.file, key, f"{name} is {what}"
                                "; only cosim nodes the orchestrator starts share a process.",
                                "leave process out for this node.")
        first = prefixes.setdefault(group, (name, plan.spec.prefix))
        if first[1] != plan.spec.prefix:
            raise ScenarioError(scenario.file, key, f"{name} and {first[0]} share process "
                                f"{group!r} but not their launch prefix.",
                                "the same prefix for every node of a process, or none.")
    return []


@rule
def launch_prefixes(scenario: Scenario, options: RunOptions) -> list:
    """A ``prefix:`` wraps a node's process: its program must be there to start it (an
    in-process run starts no process, so it uses no prefix)."""
    import shutil

    if options.in_process:
        return []
    for i, (name, plan) in enumerate(scenario.nodes.items()):
        prefix = plan.launch_prefix
        if prefix and shutil.which(prefix[0]) is None:
            raise ScenarioError(scenario.file, f"nodes[{i}] ({name}).prefix",
                                f"no program {prefix[0]!r} on PATH to start the node with.",
                                "a program that exists (e.g. prefix: 'gdb -ex run --args', "
                                "'valgrind'), installed or given by its path; or no prefix.")
    return []


@rule
def foreign_programs(scenario: Scenario, options: RunOptions) -> list:
    """Each foreign program, in the scenario's order, holds every rule of ``FOREIGN_RULES``."""
    for i, (name, plan) in enumerate(scenario.nodes.items()):
        if plan.role.is_foreign:
            for each in FOREIGN_RULES:
                each.check(scenario, i, name, plan)
    return []


@foreign_rule
def program_exists(scenario: Scenario, i: int, name: str, plan: NodePlan) -> None:
    """The program a ``command:`` names exists (relative to the scenario file, or on PATH)."""
    problem = missing_program(plan, scenario.file.parent.resolve())
    if problem:
        raise ScenarioError(scenario.file, f"nodes[{i}] ({name}).command", f"{problem}.",
                            "a command that exists: [python, path/to/program.py, ...] (paths "
                            "relative to this file) or a program on PATH.")


@foreign_rule
def not_fed_by_a_foreign_program(scenario: Scenario, i: int, name: str, plan: NodePlan
                                 ) -> None:
    """No foreign program takes an input another foreign program publishes."""
    fed_by = [inp for inp in plan.inputs if scenario.nodes[inp.producer].role.is_foreign]
    if fed_by:
        inp = fed_by[0]
        raise ScenarioError(
            scenario.file, f"nodes[{i}] ({name}).inputs", f"{inp.graph_topic} comes from "
            f"foreign program {inp.producer!r}: one foreign program feeding another is "
            "not covered (the orchestrator reads each foreign program's outputs once, to "
            "hash them, and cannot yet feed them on with their per-tick counts).",
            "a cosim node between them, or the two programs' work in one program.")


@foreign_rule
def python_gate_serves_python(scenario: Scenario, i: int, name: str, plan: NodePlan) -> None:
    """``gate: python`` is for Python programs only."""
    if plan.params.gate == PYTHON_GATE and not is_python(plan):
        raise ScenarioError(
            scenario.file, f"nodes[{i}] ({name}).params.gate", f"{plan.spec.command[0]!r} "
            "is not a Python program, so the Python gate cannot serve it.",
            "gate: rmw (or auto) for a program on rcl in another language.")


@foreign_rule
def ungated_takes_one_input(scenario: Scenario, i: int, name: str, plan: NodePlan) -> None:
    """A program no gate can serve (not Python, the RMW gate not built) takes one input at
    most: its callbacks would otherwise see samples of different ticks from run to run."""
    if gate_of(plan) is None and len(plan.inputs) > 1:
        raise ScenarioError(
            scenario.file, f"nodes[{i}] ({name}).command", f"{plan.spec.command[0]!r} is not "
            f"a Python program and the RMW gate that serves other languages is not built "
            f"({rmw_gate_library()} is missing: it is x86-64 only), so its callbacks would "
            "see samples of different ticks from run to run (not deterministic).",
            "`make install` on x86-64, a Python (rclpy) program, or a program with one "
            "input.")


@rule
def twin_has_a_topic_map(scenario: Scenario, options: RunOptions) -> list:
    """``--twin`` needs the scenario's ``twin:`` section (the topic map)."""
    if options.twin and scenario.model.twin is None:
        raise ScenarioError(scenario.file, "twin", f"--twin {options.twin}: the scenario has no "
                            "twin: section (the topic map)", "a twin: section, e.g. twin: "
                            "{subscribe: {/odom: /real/odom}} (see scenarios/twin.yaml)")
    return []


@rule
def listen_addresses(scenario: Scenario, options: RunOptions) -> list:
    """The live view and rosbridge can listen on their addresses (else a ValueError naming
    the option)."""
    problems = address_problems(options.live_address, options.rosbridge_address)
    if problems:
        raise ValueError("; ".join(problems))
    return []


@rule
def out_is_a_directory(scenario: Scenario, options: RunOptions) -> list:
    """``out`` (--out) can receive the run directory: no file where a directory must be,
    writable (else a ValueError naming the option)."""
    from plan.run_paths import out_problem

    if problem := out_problem(options.out):
        raise ValueError(problem)
    return []


@rule
def scenario_warnings(scenario: Scenario, options: RunOptions) -> list:
    """The scenario's warnings are the run's; a strict run refuses the first of them."""
    warnings = list(scenario.warnings)
    if options.strict and warnings:
        first = warnings[0]
        why = "refused by --strict (strict=True)" + (
            f"; {len(warnings) - 1} more warning(s)" if len(warnings) > 1 else "")
        if isinstance(first, ScenarioNotice):
            raise first.as_error(why)
        raise ScenarioError(scenario.file, "", f"{first} ({why})")
    return warnings


@rule
def exposed_endpoints(scenario: Scenario, options: RunOptions) -> list:
    """A warning for each live endpoint reachable from other machines."""
    return list(exposure_warnings(options.live_address, options.rosbridge_address))
