"""manifest.json: what ran, with which software, what came out, and what it cost."""

from __future__ import annotations

import hashlib
import json
import logging
import platform
import resource
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING, Any

from orchestrator.outputs.swarm import swarm_entry
from orchestrator.outputs.topic_digests import digest_of_topics, digest_versions, topic_digests
from plan.gates import FOREIGN_OUTPUT_RULE
from plan.run_paths import RunPaths
from plan.timeutil import tick_text, tick_time_ns
from runtime.timing import read_summary

log = logging.getLogger("cosim")
if TYPE_CHECKING:
    from plan.scenario import Scenario


def software_versions() -> dict[str, str]:
    """Versions of python and the packages a result depends on."""
    out = {"python": platform.python_version()}
    for name, dist in (("mujoco", "mujoco"), ("rclpy", "ros-jazzy-rclpy"),
                       ("zenoh", "eclipse-zenoh"), ("cosim", "cosim")):
        try:
            out[name] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


def startup_entry(outcome) -> dict[str, Any]:
    """Start-up: from the orchestrator process's creation (the command) to the first tick,
    from the run's start (scenario checked) to it, and how node processes were started."""
    spawned = {proc.started for _, proc in outcome.node_stats.values() if proc}
    first = outcome.command_to_first_tick_s
    return {"command_to_first_tick_s": round(first, 3) if first is not None else None,
            "run_start_to_first_tick_s": (round(outcome.start_s, 3)
                                          if outcome.start_s is not None else None),
            "node_processes": "/".join(sorted(spawned)) or None}


def node_entry(stats, proc) -> dict[str, Any]:
    """Per-node cost: CPU, peak memory, ticks served, mean and worst step time, and where
    the node's run loop spent its wall time (``time_s``, written by the node at its end)."""
    entry: dict[str, Any] = {"ticks": stats.ticks}
    if stats.ticks:
        entry["step_ms_mean"] = round(stats.step_ns_total / stats.ticks / 1e6, 4)
        entry["step_ms_worst"] = round(stats.step_ns_worst / 1e6, 4)
    if stats.ready_s is not None:
        entry["ready_s"] = round(stats.ready_s, 3)
    if proc is not None:
        entry.update(pid=proc.popen.pid, started=proc.started, exit=proc.exit_text(),
                     cpu_s=round(proc.cpu_s, 3),
                     peak_rss_mb=round(proc.peak_rss / 2**20, 1), log=str(proc.log_path.name))
        if proc.pss:
            entry.update(end_pss_mb=round(proc.pss / 2**20, 1),
                         end_uss_mb=round(proc.uss / 2**20, 1))
        split = read_summary(RunPaths(proc.log_path.parent.parent).timing(proc.name))
        if split is not None:
            entry["time_s"] = split
    return entry


def _served(schedule, name: str, ticks: int) -> int:
    """How many activations node ``name`` served in the first ``ticks`` ticks (a robot's
    node only inside its robot's window: ``plan.schedule``)."""
    return schedule.activations(name, until=ticks)


def in_process_entries(scenario: Scenario, ticks: int, result=None) -> dict[str, Any]:
    """Per-node entries of an in-process run: activations served, mean and worst step time
    (CPU and memory are the one process's, under 'orchestrator')."""
    out = {}
    for name in scenario.schedule.order:
        entry: dict[str, Any] = {
            "ticks": _served(scenario.schedule, name, ticks)}
        n, total, worst = (result.step_ns.get(name) if result else None) or (0, 0, 0)
        if n:
            entry.update(step_ms_mean=round(total / n / 1e6, 4),
                         step_ms_worst=round(worst / 1e6, 4))
        out[name] = entry
    return out


def own_cost(outcome=None) -> dict[str, float]:
    """This process's CPU time, peak memory (all of an in-process run's nodes) and its PSS
    and USS at the run's end (``end_pss_mb``, ``end_uss_mb``; in a multi-process run taken
    with the node processes', just before they were stopped, so that PSS summed over the
    orchestrator and the nodes counts the pages forked nodes share with it once)."""
    usage = resource.getrusage(resource.RUSAGE_SELF)
    out = {"cpu_s": round(usage.ru_utime + usage.ru_stime, 3),
           "peak_rss_mb": round(usage.ru_maxrss / 1024, 1)}
    import os

    from orchestrator.lockstep.supervisor import memory_of

    supervisor = getattr(outcome, "supervisor", None)
    pss, uss = supervisor.own_memory if supervisor is not None else memory_of(os.getpid())
    if pss:
        out.update(end_pss_mb=round(pss / 2**20, 1), end_uss_mb=round(uss / 2**20, 1))
    return out


def relative(path: Path | None, run_dir: Path) -> str | None:
    """A path inside the run directory as a relative text, None when there is none."""
    if path is None:
        return None
    try:
        return str(Path(path).relative_to(run_dir))
    except ValueError:
        return str(path)


def file_entry(path: Path | None) -> dict[str, Any] | None:
    """A file's name and sha256 (the world a run loaded)."""
    if path is None or not Path(path).is_file():
        return None
    return {"file": str(path), "sha256": hashlib.sha256(Path(path).read_bytes()).hexdigest()}


def scenario_entry(scenario: Scenario) -> dict[str, Any]:
    """Which scenario ran: name, file, hash, overrides, world, planned length."""
    return {"name": scenario.name, "file": str(scenario.file), "sha256": scenario.sha256,
            "overrides": scenario.overrides, "world": file_entry(scenario.world),
            "planned_ticks": scenario.schedule.n_ticks}


def outputs_entry(outcome) -> dict[str, Any]:
    """Where the outputs are, relative to the run directory (None: not written)."""
    run_dir = outcome.run_dir
    paths = RunPaths(run_dir)
    return {"bag": relative(outcome.bag, run_dir), "report": relative(outcome.report, run_dir),
            "usd": relative(getattr(outcome, "usd", None), run_dir),
            "logs": relative(paths.logs, run_dir),
            "parts": relative(paths.parts, run_dir) if paths.parts.exists() else None}


def digests_entry(scenario: Scenario, outcome) -> dict[str, Any]:
    """Per-topic digests (from the bag), the rendered topics, the digest without them, and
    the versions a digest depends on (see orchestrator.outputs.topic_digests)."""
    rendered = list(getattr(outcome, "rendered_topics", []))
    topics: dict[str, str] = {}
    if outcome.bag is not None:
        try:
            topics = topic_digests(outcome.bag, scenario.tick_ns)
        except Exception as exc:  # noqa: BLE001 - the manifest must still be written
            log.error("could not compute the per-topic digests: %s", exc)
    finished = outcome.result is not None and bool(topics)
    return {"digest_without_rendered": (digest_of_topics(topics, set(rendered))
                                        if finished else None),
            "rendered_topics": rendered,
            "topic_digests": topics,
            "digest_versions": digest_versions(getattr(outcome, "renderer", None))}


def foreign_entry(scenario: Scenario) -> dict[str, Any]:
    """Per foreign program, the gate that serves it ('python', 'rmw' or None), the rule its
    outputs follow: what its consumers see, and the message counts the scenario declares
    exactly (checked at every tick)."""
    out = {}
    for name, plan in scenario.nodes.items():
        if not plan.role.is_foreign:
            continue
        params = plan.params
        if plan.role.is_gated:
            rule = FOREIGN_OUTPUT_RULE
            exact = {plan.output_names[own]: n for own, n in params.per_activation.items()}
        else:
            rule = ("not gated: counted, its n-th message on an output is its sample of its "
                    "n-th activation")
            exact = {graph: params.count(own) for own, graph in plan.output_names.items()}
        out[name] = {"gated": plan.role.is_gated, "gate": plan.gate, "outputs": rule,
                     "exact_counts": exact, "silent_at_start": params.silent_at_start}
    return out


def build_manifest(scenario: Scenario, outcome, options) -> dict[str, Any]:
    """The manifest as a dict."""
    result = outcome.result
    ticks = result.ticks if result else 0
    sim_s = tick_time_ns(max(ticks - 1, 0), scenario.tick_ns) / 1e9
    metrics = {k: v for m in (result.metrics.values() if result else []) for k, v in m.items()}
    nodes = {name: node_entry(stats, proc) for name, (stats, proc) in outcome.node_stats.items()}
    if options.in_process and not nodes:
        nodes = in_process_entries(scenario, ticks, result)
    return {
        "scenario": scenario_entry(scenario),
        "seed": scenario.model.seed,
        "transport": "in-process" if options.in_process else scenario.model.transport,
        "versions": software_versions(),
        "digest": result.digest if result else None,
        **digests_entry(scenario, outcome),
        "outcome": {"status": outcome.status, "success": outcome.success,
                    "collisions": outcome.collisions, "error": outcome.error,
                    "metrics": metrics, "stopped_early": bool(result and result.stopped_early),
                    "metrics_by_node": result.metrics if result else {}},
        "ticks": ticks,
        "tick_ns": tick_text(scenario.tick_ns),
        "sim_time_s": sim_s,
        "wall_time_s": round(outcome.wall_s, 3),
        "start_s": round(outcome.start_s, 3) if outcome.start_s is not None else None,
        "startup": startup_entry(outcome),
        "loop_s": round(outcome.loop_s, 4) if outcome.loop_s is not None else None,
        "ticks_per_s": round(ticks / outcome.loop_s, 1) if outcome.loop_s else None,
        "real_time_factor": round(sim_s / outcome.wall_s, 2) if outcome.wall_s > 0 else None,
        "loop_real_time_factor": round(sim_s / outcome.loop_s, 2) if outcome.loop_s else None,
        "orchestrator": own_cost(outcome),
        "nodes": nodes,
        "foreign": foreign_entry(scenario),
        "outputs": outputs_entry(outcome),
        "options": options.as_dict(),
        "warnings": list(getattr(outcome, "warnings", [])),
        "notes": [note.as_dict() for note in getattr(outcome, "notes", [])],
        "live": getattr(outcome, "live", None) or None,
        "swarm": swarm_entry(scenario, result.metrics if result else {}),
        "write_failure": getattr(outcome, "write_failure", None),
        "unfinished": getattr(outcome, "unfinished", None),
    }


def write_manifest(scenario: Scenario, outcome, options) -> None:
    """Write manifest.json into the run directory."""
    manifest = build_manifest(scenario, outcome, options)
    from runtime.disk import write_atomically

    write_atomically(RunPaths(outcome.run_dir).manifest, json.dumps(manifest, indent=2) + "\n",
                     outcome.run_dir)
