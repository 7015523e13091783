"""The rules a run applies to a checked scenario before it starts anything, whoever starts
it (the command line, the Python API or the pytest plugin): what this kind of run cannot
serve is refused as a ScenarioError naming the file and the fix, and what deserves a word
is returned as warnings."""

from __future__ import annotations

from plan.errors import ScenarioError
from plan.options import RunOptions
from plan.scenario import Scenario


def check_run(scenario: Scenario, options: RunOptions) -> list[str]:
    """Refuse what this run cannot serve; return the scenario's warnings."""
    foreign = [name for name, plan in scenario.nodes.items() if plan.foreign]
    if options.in_process and foreign:
        raise ScenarioError(scenario.file, "", "in-process runs step classes only; node(s) "
                            f"{', '.join(foreign)} are foreign programs (command:).",
                            "run without --in-process (in_process=False) for this scenario.")
    if scenario.model.transport == "zenoh" and foreign and not options.in_process:
        raise ScenarioError(scenario.file, "transport", "zenoh carries cosim nodes only; "
                            f"node(s) {', '.join(foreign)} are foreign ROS 2 programs "
                            "(command:) that talk DDS.", "transport: ros2 for this scenario.")
    return list(scenario.warnings)
