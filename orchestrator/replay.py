"""``--replay RUN_DIR``: run a recorded run again in lockstep, from its record.

The run directory's manifest names the scenario file, its sha256 and the overrides; its bag
holds every message that entered from outside at the tick it entered
(``orchestrator.proxies.arrivals_record``). A replay loads the same scenario with the same
overrides, runs as many ticks as the record has, and feeds each recorded arrival to the
external node at its tick. Nothing from outside enters a replay, so every replay gives one
digest, multi-process and in-process, and it is the recorded run's digest: a run paced on
the wall clock (a twin) ran in lockstep too, its outside inputs entering at the ticks
recorded, so wall time decided only when they came, which the record keeps.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from descriptions.load import load_scenario
from orchestrator.proxies.arrivals_record import external_topic
from plan.errors import ScenarioError
from plan.roles import NodeRole
from plan.run_paths import RunPaths
from plan.scenario import Scenario
from plan.timeutil import parse_tick_ns, tick_time_ns


@dataclass
class Recorded:
    """What a replay needs from a run directory."""

    scenario: Scenario
    arrivals: dict[int, dict[str, Any]]  # tick -> external topic -> message
    digest: str | None  # the recorded run's digest

    def __call__(self, tick: int) -> dict[str, Any]:
        """What entered at ``tick`` (a Replay for the external node)."""
        return dict(self.arrivals.get(tick, {}))

    @property
    def count(self) -> int:
        """How many messages entered the recorded run from outside."""
        return sum(len(v) for v in self.arrivals.values())


def load_recorded(run_dir: Path, extra_overrides: dict | None = None) -> Recorded:
    """The scenario and arrivals of a recorded run; ScenarioError (exit 2) when the directory
    is no finished run, its scenario file is gone or changed, or options would change it."""
    paths = RunPaths(Path(run_dir))
    where = paths.manifest
    if not where.is_file():
        raise ScenarioError(where, "--replay", f"{run_dir} has no manifest.json",
                            "a run directory written by cosim-orchestrate, e.g. "
                            "runs/nav-20250101-120000")
    manifest = json.loads(where.read_text())
    if extra_overrides:
        raise ScenarioError(where, "--replay", "a replay runs the recorded scenario as it was; "
                            f"it takes no overrides (got {', '.join(sorted(extra_overrides))})",
                            "--replay RUN_DIR without --seed, --duration, --set, --transport "
                            "(--in-process, --out and how-the-work-is-done options are fine)")
    entry = manifest.get("scenario") or {}
    file = Path(entry.get("file", ""))
    if not file.is_file():
        raise ScenarioError(where, "scenario.file", f"the recorded scenario {file} is gone",
                            "the run's scenario file at the path the manifest names")
    if not paths.bag.is_dir():
        raise ScenarioError(where, "outputs.bag", f"{run_dir} has no bag to replay from",
                            "a run directory whose run wrote its bag")
    overrides = dict(entry.get("overrides") or {})
    ticks = int(manifest.get("ticks") or 0)
    planned = int(entry.get("planned_ticks") or 0)
    if 1 < ticks < planned:
        # stopped from outside (or at the goal, where the replay stops anyway): the same end
        end_ns = tick_time_ns(ticks - 1, parse_tick_ns(manifest["tick_ns"]))
        overrides["duration"] = f"{end_ns}ns"
    scenario = load_scenario(file, overrides)
    if scenario.sha256 != entry.get("sha256"):
        raise ScenarioError(file, "(file)", "the scenario file changed since the run was "
                            "recorded (its sha256 differs from the manifest's)",
                            "the scenario as it was, e.g. from version control")
    arrivals = read_arrivals(paths.bag, scenario)
    admit_recorded_robots(scenario, arrivals)
    return Recorded(scenario, arrivals, manifest.get("digest"))


def admit_recorded_robots(scenario: Scenario, arrivals: dict[int, dict[str, Any]]) -> None:
    """Open and close the windows of the robots clients brought in and took out, at the
    ticks their edits entered (``LockstepMaster._admit_robots`` did so in the recorded run),
    before any node is made: the replay's nodes run the same windows."""
    from plan.events import parse_edits
    from plan.interactive import WORLD_EDITS_TOPIC
    from plan.robots import BY_CLIENT

    layout = scenario.robots
    planned = set() if layout is None else {r.name for r in layout.robots
                                            if r.enter_ns == BY_CLIENT}
    seen = 0
    for tick in sorted(arrivals):
        message = arrivals[tick].get(WORLD_EDITS_TOPIC)
        if message is None:
            continue
        edits = parse_edits(message.data)
        for edit in edits[seen:]:
            if edit.robot is not None and edit.robot.name in planned:
                scenario.open_robot(edit.robot.name, tick)
            elif edit.delete in planned:
                scenario.close_robot(edit.delete, tick)
        seen = max(seen, len(edits))


def read_arrivals(bag: Path, scenario: Scenario) -> dict[int, dict[str, Any]]:
    """tick -> external topic -> message, from the bag's arrivals record."""
    from orchestrator.outputs.bag import BagReader
    from runtime.cdr.decode import decode

    external = next((p for p in scenario.nodes.values() if p.role is NodeRole.ORCHESTRATOR), None)
    classes = external.outputs if external is not None else {}
    out: dict[int, dict[str, Any]] = {}
    with BagReader(bag) as reader:
        topics = [t for t in reader.counts if external_topic(t) in classes]
        if not topics:  # (no topics would read them all)
            return out
        for recorded, stamp_ns, raw in reader.raw(topics):
            topic = external_topic(recorded)
            out.setdefault(scenario.schedule.tick_at(stamp_ns), {})[topic] = decode(
                raw, classes[topic])
    return out
