"""One run of a scenario, multi-process or in-process, from spawn to manifest.

What every run does is here: apply the run's rules, claim the ROS domain, make the run
directory, pick the driver (``orchestrator.drivers``: in-process or multi-process, one face)
and attach what the run carries beside its ticks (the live view) once through it, judge the
result, keep what was recorded whatever happens, and write the manifest. Node processes are
forked from this one once the scenario is loaded and before any transport library is
(``Supervisor.fork``), so the modules imported here at the top must not load rclpy or zenoh:
what needs them is imported after the nodes are started.
"""

from __future__ import annotations

import logging
import os
import re
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path

from orchestrator import run_domain
from orchestrator.drivers import driver_for
from orchestrator.drivers.face import OnTick, RunContext
from orchestrator.live.attachment import LiveView
from orchestrator.lockstep.loop_result import LoopResult, goal_reached
from orchestrator.lockstep.supervisor import signals_ignored
from orchestrator.outputs.manifest import write_manifest
from orchestrator.outputs.renderer import RendererProbe
from orchestrator.outputs.topic_digests import rendered_topics
from orchestrator.proxies.twin import never_reached, twin_address, twin_run
from orchestrator.run_rules import check_run
from plan.errors import ScenarioError, SimulationError
from plan.options import RunOptions
from plan.roles import NodeRole
from plan.run_paths import RunPaths, make_run_dir
from plan.scenario import Scenario
from runtime import disk
from runtime.arrivals import Arrivals, Replay
from runtime.disk import WriteFailed
from runtime.notes import Note, read_notes

log = logging.getLogger("cosim")
WRITE_FAILED = "WriteFailed: "  # in a node's error: its recording could not be written


@dataclass
class RunOutcome:
    """What a run left: status, the tick loop's result, timings and where the outputs are."""

    status: str  # success | goal_not_met | failed | interrupted | write_failed
    run_dir: Path
    result: LoopResult | None = None
    error: str | None = None
    wall_s: float = 0.0
    start_s: float | None = None
    command_to_first_tick_s: float | None = None
    loop_s: float | None = None
    bag: Path | None = None
    ticks_done: int = 0
    report: Path | None = None
    usd: Path | None = None
    success: bool = False
    collisions: int = 0
    node_stats: dict = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    notes: list[Note] = field(default_factory=list)  # what nodes told people, in tick order
    live: dict = field(default_factory=dict)  # what the live endpoints did (--live, --rosbridge)
    rendered_topics: list[str] = field(default_factory=list)  # drawn by a GL renderer
    renderer: RendererProbe | None = None  # which GL draws them (for the manifest)
    write_failure: dict | None = None  # a write that failed: where the run stopped, why
    unfinished: str | None = None  # why the run directory could not be finished, and the fix

    @property
    def digest(self) -> str | None:
        """The run digest, when the run finished."""
        return self.result.digest if self.result else None

    @property
    def paths(self) -> RunPaths:
        """The paths inside the run directory."""
        return RunPaths(self.run_dir)


def execute(scenario: Scenario, options: RunOptions, on_tick: OnTick | None = None,
            external: Arrivals | Replay | None = None) -> RunOutcome:
    """Run a checked scenario, write its run directory and manifest, return the outcome.

    The run's rules (``orchestrator.run_rules``) are applied first, whoever calls: a
    scenario this run cannot serve raises ScenarioError before anything is started or
    written; its warnings are logged and kept in the outcome. ``external`` feeds the
    scenario's external node: live arrivals (servers put messages into it while the run
    goes) or a replay of recorded ones. With ``options.rosbridge`` and no ``external``, the
    rosbridge clients' messages are the run's arrivals.
    """
    warnings = check_run(scenario, options)
    if twin_address(scenario, options, external) is not None:  # a live twin: paced, its link
        external, options, on_tick = twin_run(scenario, options, on_tick, external)
    if external is None and options.rosbridge:
        external = _arrivals_for(scenario)
    claimed = _claim_domain(scenario, options)
    paths = make_run_dir(options.out, scenario.name)
    run_dir = paths.root
    run_domain.describe(f"outputs in {run_dir}")
    disk.reserve(run_dir)  # room for the manifest, should the disk fill up
    handler = _log_to(paths.log("orchestrator"))
    for warning in warnings:
        log.warning("%s", warning)
    started = time.monotonic()
    outcome = RunOutcome("failed", run_dir, warnings=warnings)
    outcome.rendered_topics = rendered_topics(scenario)
    if outcome.rendered_topics:
        outcome.renderer = RendererProbe()
    try:
        context = RunContext(scenario, paths, options, outcome, started, external,
                             on_tick=[on_tick] if on_tick else [], attachments=[LiveView()])
        outcome.result = driver_for(options).drive(context)
        _judge(scenario, outcome)
        if unreached := never_reached(external):  # exit 3: a failure of the run, named
            outcome.status, outcome.success, outcome.error = "failed", False, unreached
            log.error("%s", unreached)
    except SimulationError as exc:
        outcome.status, outcome.error = "failed", str(exc)
        log.error("%s", exc)
        if WRITE_FAILED in str(exc):  # a node's recording hit a full disk
            _stopped_by_write(scenario, outcome, str(exc), exc.tick)
    except WriteFailed as exc:  # the orchestrator's own recording
        _stopped_by_write(scenario, outcome, str(exc), exc.tick)
        log.error("%s", exc)
    except KeyboardInterrupt:
        outcome.status, outcome.error = "interrupted", "interrupted by signal"
        log.warning("interrupted")
    finally:
        with signals_ignored():
            outcome.wall_s = time.monotonic() - started
            outcome.notes = _collect_notes(scenario, paths, outcome)
            outcome.bag = _write_bag_safely(scenario, outcome)
            full = outcome.status == "write_failed"  # no picture or stage on a full disk
            if options.picture and not full:
                outcome.report = _write_picture_safely(scenario, outcome)
            if options.export_usd and not full:
                outcome.usd = _export_usd_safely(scenario, outcome)
            if outcome.bag is not None:
                shutil.rmtree(paths.parts, ignore_errors=True)  # the bag holds it all
            elif paths.parts.is_dir() and any(paths.parts.iterdir()):
                outcome.unfinished = recovery_text(run_dir, "its bag could not be written")
            _write_manifest_safely(scenario, outcome, options)
            disk.release(run_dir)
            logging.getLogger().removeHandler(handler)
            handler.close()
            if claimed is not None:
                run_domain.release(claimed)
    return outcome


def _claim_domain(scenario: Scenario, options: RunOptions) -> int | None:
    """Claim the ROS domain of a multi-process run (orchestrator.run_domain) unless this
    process already has; the domain claimed here, to give back at the end. A domain another
    run has is a ScenarioError, raised before anything is written."""
    if options.in_process:
        return None
    text = os.environ.get("ROS_DOMAIN_ID", "").strip() or "0"
    domain = int(text) if text.isdigit() else 0
    if run_domain.claimed(domain):
        return None
    try:
        run_domain.claim(domain, f"scenario {scenario.name}")
    except run_domain.DomainInUse as exc:
        raise ScenarioError(scenario.file, "", str(exc)) from None
    return domain


def _stopped_by_write(scenario: Scenario, outcome: RunOutcome, text: str, tick: int | None
                      ) -> None:
    """A write of the run's outputs failed: the run stopped at ``tick``, the status and the
    exit code say so, the bag keeps the ticks every node recorded whole."""
    found = re.search(r"WriteFailed: (.*)", text)
    what = found.group(1).strip() if found else text
    node = re.match(r"node (\S+) failed", text)
    tick = tick if tick is not None and tick >= 0 else None
    at = f" at tick {tick}" if tick is not None else ""
    who = f"node {node.group(1)}" if node else "the orchestrator"
    outcome.status = "write_failed"
    outcome.error = f"the run stopped{at}: {who} {what}"
    paths = RunPaths(outcome.run_dir)
    complete = complete_ticks(scenario, paths, tick)
    outcome.ticks_done = complete
    outcome.write_failure = {"tick": tick, "by": who, "error": what, "complete_ticks": complete}


def complete_ticks(scenario: Scenario, paths: RunPaths, stop: int | None) -> int:
    """How many ticks, from 0, every cosim node recorded whole (each node's last recorded
    activation covers its period), and none at or after ``stop``."""
    from runtime.recording import read_part

    complete = stop if stop is not None else scenario.schedule.n_ticks
    for name, plan in scenario.nodes.items():
        path = paths.part(name)
        if plan.role.is_foreign or plan.role is NodeRole.ORCHESTRATOR or not path.exists():
            continue
        last = -1
        for tick, _, _ in read_part(path):
            last = max(last, tick)
        window = scenario.schedule.windows.get(name)  # a robot's node: its robot's ticks
        if last < 0:
            if window is None:
                return 0
            complete = min(complete, window[0])
            continue
        reach = last + scenario.schedule.periods[name]
        if window is not None and window[1] is not None and reach >= window[1]:
            continue  # it served its whole window
        complete = min(complete, reach)
    return max(complete, 0)


def recovery_text(run_dir: Path, why: str) -> str:
    """What to do with a run directory the run could not finish."""
    return (f"the run directory {run_dir} is not finished ({why}); parts/ keeps everything "
            f"recorded. To finish it, free space on {disk.file_system(run_dir)}, then run: "
            f"python -m orchestrator.outputs.finish {run_dir}")


def _write_manifest_safely(scenario: Scenario, outcome: RunOutcome, options: RunOptions
                           ) -> None:
    """The manifest, written whole or not at all (runtime.disk.write_atomically, with the
    run's reserve of space); when even that fails, say how to recover."""
    try:
        write_manifest(scenario, outcome, options)
    except (WriteFailed, OSError) as exc:
        log.error("could not write manifest.json: %s", exc)
        if outcome.status not in ("failed", "interrupted"):
            outcome.status = "write_failed"
        outcome.unfinished = (f"the run directory {outcome.run_dir} has no manifest ({exc}); "
                              "its logs/ and parts/ (or bag/) keep what was recorded. Free "
                              "space and run the scenario again to have a complete run")


def _collect_notes(scenario: Scenario, paths: RunPaths, outcome: RunOutcome) -> list[Note]:
    """The nodes' notes of the run's ticks (in-process: from the loop; multi-process: from
    each node's notes file, without what a node ran ahead past the stop), logged here."""
    if outcome.result is not None and outcome.result.notes:
        notes = list(outcome.result.notes)
    else:
        notes = [n for name in scenario.nodes for n in read_notes(paths.notes(name))]
    if outcome.result is not None:
        notes = [n for n in notes if n.tick < outcome.result.ticks]
    order = {name: i for i, name in enumerate(scenario.schedule.order)}
    notes.sort(key=lambda n: (n.tick, order.get(n.node, len(order))))
    for note in notes:
        log.info("note: %s", note.line())
    return notes


def _write_bag_safely(scenario: Scenario, outcome: RunOutcome) -> Path | None:
    """Write the bag from what was recorded; a failure here must not hide the run's own
    (a bag cut short is removed: the parts stay, and the run directory says how to finish).
    A run stopped by a failed write keeps the ticks every node recorded whole."""
    ticks = outcome.result.ticks if outcome.result else outcome.ticks_done
    finished = outcome.result is not None or outcome.status == "write_failed"
    try:
        from orchestrator.outputs.bag import write_bag

        return write_bag(scenario, outcome.run_dir, ticks, finished=finished)
    except Exception as exc:  # noqa: BLE001 - reported, and the parts stay on disk
        log.error("could not write the bag: %s", exc)
        shutil.rmtree(outcome.paths.bag, ignore_errors=True)
        if isinstance(exc, OSError) and outcome.status in ("success", "goal_not_met"):
            outcome.status = "write_failed"
            failed = WriteFailed(exc.filename or outcome.paths.bag, exc)
            outcome.error = f"the run finished but its bag could not be written: {failed}"
            outcome.write_failure = {"tick": None, "by": "the orchestrator",
                                     "error": str(failed), "complete_ticks": ticks}
        return None


def _write_picture_safely(scenario: Scenario, outcome: RunOutcome) -> Path | None:
    try:
        from orchestrator.outputs.picture import write_report_png
        from orchestrator.outputs.swarm_picture import write_swarm_png

        swarm = scenario.robots is not None and len(scenario.robots.robots) > 1
        write = write_swarm_png if swarm else write_report_png  # one robot: nav's report
        return write(scenario, outcome.run_dir, outcome.bag, outcome)
    except Exception as exc:  # noqa: BLE001 - the run's data stays; only the picture is lost
        log.error("could not draw report.png: %s", exc)
        return None


def _export_usd_safely(scenario: Scenario, outcome: RunOutcome) -> Path | None:
    """--export-usd: the run as run.usda, built from the bag after the run (digest untouched)."""
    if outcome.bag is None or scenario.world is None:
        log.error("no USD export: the run has no bag or no world")
        return None
    from orchestrator.outputs.usd_export import export_run_usd

    started = time.monotonic()
    try:
        out = export_run_usd(scenario.world, outcome.bag, scenario.tick_ns, outcome.paths.usd,
                             scenario.robots)
    except Exception as exc:  # noqa: BLE001 - the run's data stays; only the stage is lost
        log.error("could not write %s: %s", outcome.paths.usd.name, exc)
        return None
    log.info("wrote %s in %.2f s", out, time.monotonic() - started)
    return out


def _arrivals_for(scenario: Scenario) -> Arrivals | None:
    """Live arrivals for the scenario's external node, when it has one."""
    plan = next((p for p in scenario.nodes.values() if p.role is NodeRole.ORCHESTRATOR), None)
    return Arrivals(plan.outputs) if plan is not None else None


def _judge(scenario: Scenario, outcome: RunOutcome) -> None:
    metrics = outcome.result.metrics
    collisions = int(sum(m.get("collisions", 0) for m in metrics.values()))
    reached = goal_reached(metrics)
    spec = scenario.model.success
    ok = collisions <= spec.max_collisions
    if spec.reach_goal and scenario.model.has_goal:
        ok = ok and reached
    outcome.collisions, outcome.success = collisions, ok
    outcome.status = "success" if ok else "goal_not_met"


class _LogFile(logging.FileHandler):
    """The orchestrator's log file; on a full disk it stops writing, without a traceback
    per line (the run's own recording says what failed)."""

    def handleError(self, record: logging.LogRecord) -> None:  # noqa: N802 - logging's name
        """Stop writing after the first failure."""
        self.setLevel(logging.CRITICAL + 1)


def _log_to(path: Path) -> logging.Handler:
    path.parent.mkdir(parents=True, exist_ok=True)
    handler = _LogFile(path)
    handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(message)s"))
    root = logging.getLogger()
    root.addHandler(handler)
    root.setLevel(logging.INFO)
    return handler
