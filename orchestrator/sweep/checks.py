"""Everything a sweep checks before it starts or writes anything (bad input: exit 2).

The scenario is loaded and checked for the run mode with its first seed and every key
given a single value, then once per swept value (each key's values one at a time over
that: the sum of the values, not their product, so that a large sweep starts at once). A value
that is only wrong in combination with another one fails that run, named, with status
'error'.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import nodes  # noqa: F401 - provides the node kinds to the plan (plan.kinds)
from descriptions.load import load_scenario
from orchestrator.run_rules import check_run
from orchestrator.sweep.combinations import RunSpec, parse_seeds, parse_sweep_sets, plan_runs
from plan.errors import ScenarioError
from plan.options import RunOptions
from plan.roles import NodeRole

PLAN_NAME = "sweep.json"


@dataclass
class CheckedSweep:
    """A sweep that may start: its scenario's name, swept values, runs and plan document."""

    name: str
    values: dict[str, list[Any]]
    specs: list[RunSpec]
    plan_doc: dict[str, Any]


def check_sweep(args: argparse.Namespace) -> CheckedSweep:
    """Check the command line and the scenario; raise ScenarioError or ValueError."""
    seeds = parse_seeds(args.seeds)
    values = parse_sweep_sets(args.set)
    if args.jobs is not None and args.jobs < 1:
        raise ValueError(f"--jobs {args.jobs}: give 1 or more")
    if args.timeout is not None and args.timeout <= 0:
        raise ValueError(f"--timeout {args.timeout:g}: give a number of seconds above 0")
    if args.retry_failed and not args.resume:
        raise ValueError("--retry-failed goes with --resume")
    _check_out(args.out, args.scenario, args.resume)
    in_process = not args.multi_process
    options = RunOptions(in_process=in_process)
    fixed = {"seed": seeds[0], **{k: v[0] for k, v in values.items() if len(v) == 1}}
    base = load_scenario(args.scenario, fixed)
    check_run(base, options)
    for key, key_values in values.items():
        for value in key_values if len(key_values) > 1 else ():
            check_run(load_scenario(args.scenario, {**fixed, key: value}), options)
    external = [name for name, plan in base.nodes.items() if plan.role is NodeRole.USER_STARTED]
    if external and not in_process:
        raise ScenarioError(base.file, "nodes", f"node(s) {', '.join(external)} are external: "
                            "a sweep cannot wait for someone to start them.",
                            "external: false for a sweep, or in-process runs.")
    processes = 1 if in_process else len(base.nodes) + 1  # the nodes and the orchestrator
    specs = plan_runs(args.scenario, seeds, values, args.out, in_process, processes,
                      picture=not args.no_picture)
    doc = {"scenario": str(args.scenario.resolve()), "seeds": seeds, "values": values,
           "in_process": in_process, "processes_per_run": processes,
           "backend": f"ray {args.ray}" if args.ray else "local", "runs": len(specs)}
    return CheckedSweep(base.name, values, specs, doc)


def _check_out(out: Path, scenario: Path, resume: bool) -> None:
    """Refuse to mix two sweeps in one directory, or to resume another scenario's sweep."""
    plan_file = out / PLAN_NAME
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {out}: not a directory")
    if not plan_file.exists():
        return
    if not resume:
        raise ValueError(f"--out {out} already holds a sweep ({plan_file}); add --resume to "
                         "go on with it, or choose another --out")
    try:
        previous = json.loads(plan_file.read_text())["scenario"]
    except (OSError, ValueError, KeyError) as exc:
        raise ValueError(f"--resume: {plan_file} is unreadable ({exc})") from None
    if Path(previous) != scenario.resolve():
        raise ValueError(f"--resume: the sweep in {out} ran {previous}, not "
                         f"{scenario.resolve()}; choose another --out for a new sweep")
