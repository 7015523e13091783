"""cosim from Python: load a scenario, override it, run it, read what it recorded.

    from orchestrator.api import run

    result = run("scenarios/nav.yaml", seed=3, in_process=True, out="runs")
    assert result.success, result.error
    for stamp_ns, odom in result.messages("/odom"):   # nav_msgs.msg.Odometry objects
        ...

Errors are the ones the command line reports: ``ScenarioError`` (bad input, nothing was
started: exit code 2) and ``SimulationError`` (a node failed: exit code 3).
``check_node(MyNode, params)`` runs a step class through cosim's rules before it joins a
scenario (``runtime.node_check``).

Robots and objects enter and leave a run at a tick (``plan.events``): ``spawn_robot``,
``spawn_robot_swarm``, ``spawn_object`` and ``delete`` make events, and ``run(...,
events=[...])`` adds them to the scenario's (docs/tutorials/robots-enter.md):

    base = load("scenarios/swarm.yaml")
    result = run(base, in_process=True, events=[
        spawn_robot("late", at="2s", start=(-3.0, 0.0, 0.0), goal=(3.0, 0.0)),
        *spawn_robot_swarm(base, 3, at="1s", region={"x": [-1, 1], "y": [-1, 1]}),
        delete("late", at="6s")])
"""

from __future__ import annotations

import json
import warnings
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import nodes  # noqa: F401 - provides the node kinds to the plan (plan.kinds)
from descriptions.load import load_scenario
from orchestrator.execute import RunOutcome, execute
from plan.errors import ScenarioError, ScenarioWarning, SimulationError
from plan.options import RunOptions
from plan.scenario import Scenario
from runtime.arrivals import Arrivals, Replay
from runtime.node_check import NodeCheckError, NodeCheckReport, check_node

__all__ = ["EXIT_CODES", "Arrivals", "FinishedRun", "NodeCheckError", "NodeCheckReport",
           "RunOptions", "ScenarioError", "ScenarioWarning", "SimulationError", "check_node",
           "delete", "load", "overrides_for", "replay", "run", "spawn_object", "spawn_robot",
           "spawn_robot_swarm"]

EXIT_CODES = {"success": 0, "goal_not_met": 1, "failed": 3, "write_failed": 5,
              "interrupted": 130}
"""Run status -> the exit code cosim-orchestrate gives it (2 is bad input: ScenarioError)."""


def overrides_for(*, seed: int | None = None, duration: str | int | float | None = None,
                  goal: Mapping[str, float] | None = None,
                  params: Mapping[str, Mapping[str, Any]] | None = None,
                  transport: str | None = None,
                  overrides: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Dotted scenario overrides from keyword arguments.

    ``goal={'x': 1.0}`` sets goal.x only; ``params={'control': {'max_speed': 0.4}}`` sets
    nodes.control.params.max_speed only; ``overrides`` takes any dotted key as is
    ('nodes.lidar.rate': 20) and wins over the others.
    """
    out: dict[str, Any] = {}
    if seed is not None:
        out["seed"] = seed
    if duration is not None:
        out["duration"] = duration
    if transport is not None:
        out["transport"] = transport
    for key, value in (goal or {}).items():
        out[f"goal.{key}"] = value
    for node, values in (params or {}).items():
        for key, value in values.items():
            out[f"nodes.{node}.params.{key}"] = value
    out.update(overrides or {})
    return out


Event = dict[str, Any]  # one item of a scenario's events: list (plan.events.EventSpec)


def _planar(pose) -> dict[str, float]:
    """(x, y) or (x, y, yaw), or a mapping with x, y and yaw, as a pose mapping."""
    if isinstance(pose, Mapping):
        return {key: float(value) for key, value in pose.items()}
    return dict(zip(("x", "y", "yaw"), (float(v) for v in pose), strict=False))


def spawn_robot(name: str, *, at: str | int, start, goal, description: str | Path | None = None,
                urdf: Mapping[str, Any] | None = None, usd: Mapping[str, Any] | None = None
                ) -> Event:
    """An event that brings a robot in at ``at`` ('2s', '400ms'): a copy of the scenario's
    ``robots:`` description, or of ``description`` (an MJCF, URDF, xacro or USD file, read
    with ``urdf`` or ``usd`` settings as the robots: section's; paths from the working
    directory), named ``name`` (its namespace), at ``start`` and going to ``goal`` ((x, y) or
    (x, y, yaw)), with every ``for_each: robot`` node of the scenario (its lidar, its
    controller), dormant until then."""
    robot: dict[str, Any] = {"name": name, "start": _planar(start), "goal": _planar(goal)}
    if description is not None:
        robot["description"] = str(Path(description).resolve())
    for key, settings in (("urdf", urdf), ("usd", usd)):
        if settings is not None:
            settings = dict(settings)
            if "packages" in settings:
                settings["packages"] = {package: str(Path(folder).resolve())
                                        for package, folder in settings["packages"].items()}
            robot[key] = settings
    return {"at": at, "robot": robot}


def spawn_object(name: str, *, at: str | int, shape: str, pose, size=(), **more: Any) -> Event:
    """An event that puts an object in at ``at``: a box, cylinder, sphere or mesh
    (``plan.events.ObjectSpec``: ``size``, ``mesh``, ``static``, ``mass``, ``rgba``, ...)."""
    spec = {"name": name, "shape": shape, "pose": _planar(pose), **more}
    if size:
        spec["size"] = list(size)
    return {"at": at, "spawn": spec}


def delete(name: str, *, at: str | int) -> Event:
    """An event that takes the robot or object ``name`` (that an earlier event brought in)
    out at ``at``: its topics go quiet, its nodes stop being scheduled."""
    return {"at": at, "delete": name}


def spawn_robot_swarm(scenario: str | Path | Scenario, count: int, *, at: str | int,
                      region: Mapping[str, Any], goal_region: Mapping[str, Any] | None = None,
                      prefix: str = "swarm", clearance: float = 0.8, seed: int | None = None
                      ) -> list[Event]:
    """``count`` robots entering at ``at``, named PREFIX_0, ..., placed from ``seed`` (the
    scenario's by default) in ``region`` ({x: [x0, x1], y: [y0, y1]}) clear of the world's
    obstacles and of the robots there from the start, at least ``clearance`` apart; each
    goal in ``goal_region``, or its start mirrored through the region's centre."""
    from descriptions.swarm_world import swarm_model
    from descriptions.world_geometry import robot_footprint_radius, static_obstacles
    from descriptions.worldfile import compile_world, load_world_spec
    from plan.model import RobotsSpec
    from plan.obstacles import Obstacle
    from plan.robot_placement import place_robots

    loaded = load(scenario)
    layout = loaded.robots
    if layout is None:
        raise ScenarioError(loaded.file, "robots", "robots enter as copies of the robots: "
                            "section's description, and the scenario has none.",
                            "a scenario with a robots: section.")
    world = loaded.world
    obstacles = static_obstacles(compile_world(load_world_spec(world, stage_robots_too=False),
                                               world))
    footprint = robot_footprint_radius(swarm_model(world, layout.everyone),
                                       f"{layout.robots[0].name}/{layout.base_body}")
    there = [Obstacle(name=r.name, geom=-1, kind="robot", centre=r.start[:2],
                      z_range=(-1e9, 1e9), radius=footprint)
             for r in layout.robots if r.enter_ns == 0]
    spec = RobotsSpec(count=count, region=region, goal_region=goal_region,
                      name_prefix=prefix, clearance=clearance)
    placed = place_robots(loaded.file, spec, list(obstacles) + there, footprint,
                          loaded.model.seed if seed is None else seed, [])
    return [spawn_robot(r.name, at=at, start=r.start, goal=r.goal) for r in placed]


def _with_events(scenario: str | Path | Scenario, events: list[Event]) -> dict[str, Any]:
    """The override of ``events`` that adds ``events`` to the scenario's own, in time order
    (those at one time in the order given, after the scenario's). The scenario's own are
    its file's (with a loaded Scenario's overrides) as written: the checked model's have
    their robots' urdf:/usd: settings read out into the plan."""
    from plan.events import parse_time_ns
    from plan.load import read_raw

    if isinstance(scenario, Scenario):
        raw = read_raw(scenario.file, scenario.overrides)
    else:
        raw = read_raw(scenario)
    own = raw.get("events") if isinstance(raw, dict) else None
    items = [*(own if isinstance(own, list) else []), *(dict(e) for e in events)]

    def when(event: Any) -> int:
        try:
            return parse_time_ns(event["at"])
        except (TypeError, KeyError, ValueError):
            return -1  # not a time: the load that follows names its key
    items.sort(key=when)  # stable: the given order kept
    return {"events": items}


def load(scenario: str | Path | Scenario, *, events: list[Event] | None = None,
         **overrides: Any) -> Scenario:
    """Load and check a scenario file (or re-load a Scenario) with overrides; see
    ``overrides_for`` for the keywords. ``events`` are added to the scenario's events
    (``spawn_robot``, ``spawn_object``, ``delete``). Raises ScenarioError on anything
    wrong."""
    extra = overrides_for(**overrides)
    if events:
        extra.update(_with_events(scenario, events))
    if isinstance(scenario, Scenario):
        if not extra:
            return scenario
        return load_scenario(scenario.file, {**scenario.overrides, **extra})
    return load_scenario(scenario, extra)


def run(scenario: str | Path | Scenario, *, in_process: bool = False,
        out: str | Path = "runs", check: bool = True, options: RunOptions | None = None,
        external: Arrivals | Replay | None = None, real_time_factor: float | None = None,
        events: list[Event] | None = None, picture: bool | None = None,
        **overrides: Any) -> FinishedRun:
    """Run a scenario (a file or a loaded Scenario) and return its FinishedRun.

    ``in_process=True`` steps every node in this process with no transport (the reference,
    fastest); otherwise every node is its own process in lockstep over the scenario's
    transport, in the ROS domain of ``ROS_DOMAIN_ID``. Outputs go to ``out/<name>-<time>/``.
    With ``check`` (default) a node failure raises SimulationError; a missed goal never
    raises (look at ``FinishedRun.success``). Ctrl-C raises KeyboardInterrupt after the
    clean-up. ``options`` sets how the work is done (see plan.options.RunOptions; its
    ``out`` and ``in_process`` are replaced by the keywords). The scenario's warnings are
    issued as ScenarioWarning. ``external`` feeds the scenario's ``external:`` topics: an
    ``Arrivals`` that other threads put messages into while the run goes (each enters at
    the next tick of the external node), or a function tick -> {topic: message} (a replay).
    ``real_time_factor`` paces the run on the wall clock for people watching (1.0: real
    time; ``RunOptions.real_time_factor``): the same digest, in sim time / R of wall time.
    ``events`` (``spawn_robot``, ``spawn_robot_swarm``, ``spawn_object``, ``delete``) are
    added to the scenario's own: each happens at its tick, the same in every driver.
    ``picture=False`` leaves report.png out (``RunOptions.picture``: about a CPU second a
    run, for programs that run many).
    """
    loaded = load(scenario, events=events, **overrides)
    chosen = (options or RunOptions()).with_(out=Path(out), in_process=in_process)
    if real_time_factor is not None:
        chosen = chosen.with_(real_time_factor=real_time_factor)
    if picture is not None:
        chosen = chosen.with_(picture=picture)
    outcome = execute(loaded, chosen, external=external)
    for text in outcome.warnings:
        warnings.warn(text, ScenarioWarning, stacklevel=2)
    result = FinishedRun(loaded, outcome, in_process)
    if outcome.status == "interrupted":
        raise KeyboardInterrupt(f"run interrupted; outputs in {outcome.run_dir}")
    if check:
        result.raise_for_failure()
    return result


def replay(run_dir: str | Path, *, in_process: bool = False, out: str | Path = "runs",
           check: bool = True, options: RunOptions | None = None,
           real_time_factor: float | None = None) -> FinishedRun:
    """Run a recorded run again in lockstep from its run directory (``--replay``): its
    scenario and overrides, each message that entered it from outside at the tick it
    entered (orchestrator.replay). Compare ``.digest`` with the recorded manifest's."""
    from orchestrator.replay import load_recorded

    recorded = load_recorded(Path(run_dir))
    return run(recorded.scenario, in_process=in_process, out=out, check=check,
               options=options, external=recorded, real_time_factor=real_time_factor)


@dataclass
class FinishedRun:
    """A finished run: status, exit code, success, metrics, digest, outputs and messages."""

    scenario: Scenario
    outcome: RunOutcome
    in_process: bool = False

    @property
    def status(self) -> str:
        """success | goal_not_met | failed | write_failed | interrupted."""
        return self.outcome.status

    @property
    def exit_code(self) -> int:
        """The exit code cosim-orchestrate gives this run (0, 1, 3, 5 or 130)."""
        return EXIT_CODES.get(self.status, 3)

    @property
    def success(self) -> bool:
        """Whether the scenario's success criteria were met."""
        return bool(self.outcome.success)

    @property
    def digest(self) -> str | None:
        """The run digest (hex), None when the run did not finish."""
        return self.outcome.digest

    @property
    def error(self) -> str | None:
        """Why the run failed, when it did."""
        return self.outcome.error

    @property
    def run_dir(self) -> Path:
        """The run directory: manifest.json, bag/, report.png, logs/."""
        return Path(self.outcome.run_dir)

    @property
    def bag(self) -> Path | None:
        """The rosbag2 (MCAP) directory, None when nothing was recorded."""
        return Path(self.outcome.bag) if self.outcome.bag else None

    @property
    def metrics_by_node(self) -> dict[str, dict[str, float]]:
        """Each node's metrics, e.g. {'physics': {'collisions': 0.0, ...}, ...}."""
        return dict(self.outcome.result.metrics) if self.outcome.result else {}

    @property
    def metrics(self) -> dict[str, float]:
        """All nodes' metrics in one mapping (time_to_goal, path_length, min_clearance, ...)."""
        return {k: v for m in self.metrics_by_node.values() for k, v in m.items()}

    @property
    def notes(self) -> list:
        """What the nodes told people during the run (runtime.notes.Note: node, tick,
        time_ns, text), in tick order; e.g. why the controller found no path."""
        return list(self.outcome.notes)

    @property
    def ticks(self) -> int:
        """How many ticks ran."""
        return self.outcome.result.ticks if self.outcome.result else self.outcome.ticks_done

    @property
    def manifest(self) -> dict[str, Any]:
        """The run's manifest.json as a dict."""
        return json.loads(self.outcome.paths.manifest.read_text())

    def raise_for_failure(self) -> None:
        """Raise SimulationError when a node failed or the outputs could not be written
        (what cosim-orchestrate exits 3 and 5 for)."""
        if self.status in ("failed", "write_failed"):
            raise SimulationError(f"{self.error} (outputs in {self.run_dir})")

    def topics(self) -> dict[str, type]:
        """Every recorded topic and its rclpy message class (/clock included)."""
        from rosgraph_msgs.msg import Clock

        return {"/clock": Clock, **self.scenario.topics}

    def messages(self, topic: str) -> Iterator[tuple[int, Any]]:
        """(stamp in ns, rclpy message) for every message recorded on ``topic``, in order.

        The messages are the classes nodes publish (nav_msgs.msg.Odometry for /odom, ...).
        """
        from orchestrator.outputs.bag import BagReader

        if self.bag is None:
            return
        with BagReader(self.bag) as bag:
            yield from bag.messages(topic, self.topics().get(topic))

    def last(self, topic: str) -> Any:
        """The last message recorded on ``topic`` (None when there is none)."""
        last = None
        for _, msg in self.messages(topic):
            last = msg
        return last

    def summary(self) -> str:
        """One line: status, digest, key metrics and the run directory (for assert messages)."""
        shown = ", ".join(f"{k}={v:g}" for k, v in sorted(self.metrics.items())
                          if isinstance(v, int | float))
        error = f" error: {self.error};" if self.error else ""
        return (f"{self.status}: digest {self.digest or '-'};{error} {shown} "
                f"-> {self.run_dir}")
