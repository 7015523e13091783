"""The checks of a scenario model beyond its schema: names, node classes and parameters,
the world, the tick and duration, foreign output counts and algebraic loops."""

from __future__ import annotations

import math
from fractions import Fraction
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ValidationError

from plan.errors import Problems, ScenarioError, ScenarioNotice, WorldError
from plan.kinds import catalogue
from plan.model import NodeSpec, ScenarioModel
from plan.robots import RobotsLayout, merged_names, robot_of
from plan.roles import NodeRole
from plan.scenario import NodePlan
from plan.schedule import Edge, find_same_tick_cycle
from plan.timeutil import (
    NS_PER_S,
    Ns,
    exact_rate_text,
    format_ns,
    format_rate,
    gcd_ns,
    tick_at_ns,
    tick_time_ns,
)
from plan.twin import twin_problems
from plan.validation import describe_validation_errors
from plan.world_reader import WorldReader


class ScenarioChecks:
    """The semantic checks of one scenario model that follow schema validation, each raising
    a precise ScenarioError naming the file and key; a check of many independent things
    keeps each one's problem in ``found`` and goes on."""
    def __init__(self, path: Path, model: ScenarioModel, origins: dict[str, int] | None = None,
                 worlds: WorldReader | None = None, found: Problems | None = None):
        self.path = path
        self.model = model
        self.origins = origins or {}  # node name -> its entry's index in the file (templates)
        self.worlds = worlds  # the world loader's side (descriptions), for check_world
        self.found = found if found is not None else Problems()

    def fail(self, key: str, problem: str, accepted: str = "") -> ScenarioError:
        """Build the error for this file."""
        return ScenarioError(self.path, key, problem, accepted)

    def node_key(self, i: int, sub: str = "") -> str:
        """'nodes[1] (sensors).rate'-style key path."""
        name = self.model.nodes[i].name
        key = f"nodes[{self.origins.get(name, i)}] ({name})"
        return f"{key}.{sub}" if sub else key

    def check_finite(self, key: str, value: Any) -> None:
        """No NaN or infinity anywhere in a (dumped) section: a position, a speed or a
        tolerance that is not a number would fail only once the run is under way."""
        if isinstance(value, float) and not math.isfinite(value):
            raise self.fail(key, f"{value!r} is not a finite number.",
                            "a finite number (no .nan, .inf or -.inf).")
        if isinstance(value, dict):
            for sub, item in value.items():
                self.check_finite(f"{key}.{sub}" if key else str(sub), item)
        elif isinstance(value, list | tuple):
            for n, item in enumerate(value):
                self.check_finite(f"{key}[{n}]", item)

    def check_unique_names(self) -> None:
        """Node names must be unique."""
        seen: dict[str, int] = {}
        for i, spec in enumerate(self.model.nodes):
            if spec.name in seen:
                raise self.fail(self.node_key(i, "name"), f"duplicate node name {spec.name!r} "
                                f"(also nodes[{seen[spec.name]}]).",
                                "a name used by one node only.")
            seen[spec.name] = i

    def node_class(self, i: int, spec: NodeSpec) -> tuple[str, type]:
        """The step class named by kind or module (or the stand-in of a foreign command)."""
        kinds = catalogue()
        given = [key for key in ("kind", "module", "command") if getattr(spec, key) is not None]
        if len(given) != 1:
            raise self.fail(self.node_key(i), "give exactly one of 'kind', 'module' or "
                            f"'command' (found {', '.join(given) or 'none'}).",
                            f"kind: one of {', '.join(kinds.listed)}; "
                            "or module: 'package.module:Class'; or command: [program, args...] "
                            "for a foreign ROS 2 program.")
        if spec.command is not None:
            return kinds.foreign, kinds.load(kinds.foreign)
        if spec.kind is not None:
            if spec.kind not in kinds.kinds:
                raise self.fail(self.node_key(i, "kind"), f"unknown node kind {spec.kind!r}.",
                                f"one of {', '.join(kinds.listed)}; or module: "
                                "'package.module:Class' for a node class of your own.")
            try:
                return kinds.kinds[spec.kind], kinds.load(kinds.kinds[spec.kind])
            except Exception as exc:  # noqa: BLE001 - report, don't crash: nothing has started
                raise self.fail(self.node_key(i, "kind"), f"node kind {spec.kind!r} cannot be "
                                f"loaded from {kinds.kinds[spec.kind]}: {exc}.",
                                "a kind whose code is installed; check the installation."
                                ) from None
        try:
            return spec.module, kinds.load(spec.module)
        except Exception as exc:  # noqa: BLE001 - any import failure is the user's to fix
            raise self.fail(self.node_key(i, "module"), f"cannot load {spec.module!r}: {exc}.",
                            "'package.module:Class' importable here, a StepNode subclass."
                            ) from None

    def node_params(self, i: int, spec: NodeSpec, cls: type) -> BaseModel:
        """The node's parameters checked against its class's Params model."""
        try:
            return cls.Params.model_validate(spec.params,
                                             context={"scenario_dir": self.path.parent})
        except ValidationError as exc:
            raise ScenarioError.every([
                self.fail(self.node_key(i, f"params.{key}" if key else "params"), problem,
                          accepted)
                for key, problem, accepted in describe_validation_errors(exc, spec.params,
                                                                        cls.Params)]) from None

    def world_path(self, needed: bool) -> tuple[Path | None, object]:
        """The world file, resolved relative to the scenario file, which must exist, and its
        compiled model (None when no node needs one)."""
        if self.model.world is None:
            if needed:
                raise self.fail("world", "a node of this scenario needs a world file, none given.",
                                "world: path to an MJCF (.xml) or USD (.usda, .usdc, .usd) file, "
                                "relative to this file.")
            return None, None
        world = (self.path.parent / self.model.world).resolve()
        if world.is_dir():
            raise self.fail("world", f"{self.model.world!r} is a directory ({world}), not a "
                            "world file.", "the path of an MJCF (.xml) or USD (.usda, .usdc, "
                            ".usd) file, relative to this file.")
        if not world.is_file():
            raise self.fail("world", f"world file {self.model.world!r} does not exist "
                            f"(looked for {world}).", "a path relative to the scenario file.")
        return world, (self.check_world(world) if needed else None)

    def check_world_fit(self, classes: dict, params: dict, world_model,
                        layout: RobotsLayout | None = None) -> list[str]:
        """Each node's own check of the world (its robot there, start and goal placeable):
        problems are kept in ``found``; what only deserves a word (a goal its map cannot
        reach) is returned as warnings. A world node of a swarm is given its first robot's
        model where a description reader made it (``WorldReader.described_robot``): its
        names are the model's, not the parameters'."""
        goal = self.model.goal.model_dump() if self.model.goal else None
        with self.found.collecting():
            self.check_joint_goal(world_model)
        for i, (_, cls) in classes.items():
            if not cls.needs_world or not hasattr(cls, "world_problems"):
                continue
            robots = self.model.nodes[i].robots
            if robots and getattr(cls, "every_robot", False):  # each robot is checked as
                # the first one is, under its names in the swarm world
                described = (self.worlds.described_robot(layout, robots[0])
                             if layout is not None else None)
                problems = list(cls.world_problems(params[i], world_model, goal,
                                                   robot=robots[0], described=described))
            else:
                problems = list(cls.world_problems(params[i], world_model, goal))
            if hasattr(cls, "period_problems"):
                problems += cls.period_problems(params[i], world_model,
                                                self.model.nodes[i].period_ns)
            for key, problem, accepted in problems:
                where = key if key.startswith("goal") else self.node_key(i, key)
                self.found.add(self.fail(where, f"{problem} (world {self.model.world})",
                                         accepted))
        if self.found.errors:
            return []  # a goal's reachability is judged in a world the nodes fit
        start = robot_start(params)
        warnings = []
        for i, (_, cls) in classes.items():
            if not cls.needs_world or not hasattr(cls, "world_warnings"):
                continue
            for key, text in cls.world_warnings(params[i], world_model, goal, start):
                where = key if key.startswith("goal") else self.node_key(i, key)
                warnings.append(ScenarioNotice(
                    self.path, where, f"{text} (world {self.model.world})",
                    "a goal the robot can reach from its start: move the goal, the start or "
                    "the obstacles named."))
        return warnings

    def check_joint_goal(self, world_model) -> None:
        """Every joint of ``joint_goal`` is a hinge or slide joint of the world."""
        goal = self.model.joint_goal
        if goal is None:
            return
        joints = {world_model.joint(j).name: int(world_model.jnt_type[j])
                  for j in range(world_model.njnt)}
        for name in goal.positions:
            if joints.get(name) not in (2, 3):  # mjJNT_SLIDE, mjJNT_HINGE: one position each
                raise self.fail(f"joint_goal.positions.{name}", f"the world has no hinge or "
                                f"slide joint {name!r} (world {self.model.world}); its joints: "
                                f"{', '.join(n for n in joints if n) or 'none'}.",
                                "names of the robot's hinge or slide joints.")

    def check_robot_needs(self, classes: dict, params: dict, world: Path,
                          layout: RobotsLayout | None, world_model) -> None:
        """What each node needs of the robot model the run gives it (a lidar to cast from, a
        camera to render, the arm's joints: ``StepNode.robot_problems``), against that model,
        read by the names the nodes' parameters give; a template's instances once (every
        robot of a swarm has the one description), the world node for its first robot."""
        given = [(self.model.nodes[i].name, cls.description_names(params[i]))
                 for i, (_, cls) in classes.items()]  # as the run reads it: every node's
        try:
            robots = self.worlds.robot_models(world, layout, merged_names(given))
        except WorldError as exc:
            raise self.fail("world", f"the robot cannot be read from it: {exc.reason}.",
                            "a robot with the parts its nodes' parameters name.") from None
        except ValueError as exc:
            raise self.fail("nodes", f"{exc}.", "one name for each part of the robot, in "
                            "every node that names it.") from None
        errors, seen = [], set()
        for i, (_, cls) in classes.items():
            name = self.model.nodes[i].name
            if not cls.needs_world or self.origins.get(name, i) in seen:
                continue
            seen.add(self.origins.get(name, i))
            own = robot_of(name)
            for robot in [r for r in robots if own is None or r.name == own][:1]:
                errors += [self.fail(self.node_key(i, key), problem, accepted)
                           for key, problem, accepted in cls.robot_problems(params[i], robot,
                                                                            world_model)]
        if errors:
            raise ScenarioError.every(errors)

    def check_world(self, world: Path):
        """Load the world once here, so a file MuJoCo cannot load fails before any node starts."""
        try:
            return self.worlds.world_model(world)
        except WorldError as exc:
            raise self.fail("world", f"{exc}", "an MJCF (.xml) or USD (.usda, .usdc, .usd) "
                            "world that MuJoCo loads; USD colliders must be Cube, Sphere, "
                            "Cylinder, Capsule, Z-axis Plane or Mesh prims.") from None

    def tick_ns(self) -> Ns:
        """The tick: given, or the gcd of all node periods (exact: 1/150 s for 30 Hz with
        50 Hz); every period a whole number of ticks."""
        periods = [spec.period_ns for spec in self.model.nodes]
        tick = self.model.tick or gcd_ns(periods)
        errors = [self.fail(self.node_key(i, "rate"),
                            f"a rate of {format_rate(spec.period_ns)} Hz has a period of "
                            f"{format_ns(spec.period_ns)}, not a whole number of "
                            f"{format_ns(tick)} ticks.", _rates_that_fit(spec.period_ns, tick,
                                                                         gcd_ns(periods)))
                  for i, spec in enumerate(self.model.nodes) if spec.period_ns % tick]
        if errors:
            raise ScenarioError.every(errors)
        if tick < 1:
            raise self.fail("nodes", f"the rates give a tick of {format_ns(tick)}, shorter than "
                            "1 ns: ticks would share a time stamp.",
                            "rates whose periods have a common divisor of at least 1 ns.")
        return tick

    def last_tick(self, tick_ns: Ns) -> int:
        """The index of the last tick; the duration must be a whole number of ticks, or the
        rounded time of one (``tick_time_ns``: what a replay of a run stopped early at a
        fractional tick's stamp gives)."""
        last = tick_at_ns(self.model.duration, tick_ns)
        if tick_time_ns(last, tick_ns) != self.model.duration:
            whole = Fraction(tick_ns).numerator  # the shortest whole-ns run of whole ticks
            raise self.fail("duration", f"{format_ns(self.model.duration)} is not a whole number "
                            f"of {format_ns(tick_ns)} ticks.", "a multiple of the tick, e.g. "
                            f"{format_ns((self.model.duration // whole + 1) * whole)}.")
        return last

    def check_foreign_counts(self, nodes: dict[str, NodePlan], edges: list[Edge]) -> None:
        """An ungated foreign program (no gate serves it, ``plan.gates``: not Python and
        the RMW gate not built, so nothing acknowledges its ticks) is known
        to have finished a tick only by counting its messages, and its consumers map its
        n-th message to its n-th activation: an output others consume must then carry one
        message per activation. A gated program may publish any number (its consumers see
        the latest sample, see ``runtime.gated_output``)."""
        consumed = {e.topic for e in edges}
        for i, spec in enumerate(self.model.nodes):
            plan = nodes[spec.name]
            if plan.role is not NodeRole.UNGATED:
                continue
            for own, graph in plan.output_names.items():
                if graph in consumed and plan.params.silent_at_start:
                    raise self.fail(self.node_key(i, "params.silent_at_start"),
                                    f"{graph} is consumed by other nodes, which need the "
                                    "program's sample of tick 0, and this program "
                                    "(ungated: not Python, RMW gate not built) publishes "
                                    "nothing then.",
                                    "false, or no node consuming its outputs.")
                if graph in consumed and plan.params.count(own) != 1:
                    raise self.fail(self.node_key(i, f"params.per_activation.{own}"),
                                    f"{graph} is consumed by other nodes, which take one "
                                    f"message per activation of this program (ungated: "
                                    "not Python, RMW gate not built), not "
                                    f"{plan.params.count(own)}.",
                                    "1 for a consumed topic (or leave it out).")

    def check_twin(self, nodes: dict[str, NodePlan]) -> None:
        """A twin's topic map names only topics of the run (plan/twin.py)."""
        if self.model.twin is None:
            return
        external = {t: c for p in nodes.values() if p.role is NodeRole.ORCHESTRATOR
                    for t, c in p.outputs.items()}
        topics = {t: c for p in nodes.values() for t, c in p.outputs.items()}
        errors = [self.fail(key, problem, accepted)
                  for key, problem, accepted in twin_problems(self.model.twin, external, topics)]
        if errors:
            raise ScenarioError.every(errors)

    def check_cycles(self, edges: list[Edge]) -> None:
        """Refuse a cycle of same_tick edges, naming it."""
        cycle = find_same_tick_cycle([n.name for n in self.model.nodes], edges)
        if cycle:
            raise self.fail("nodes", f"the same_tick inputs form an algebraic loop "
                            f"{' -> '.join(cycle)} with no delay to break it.",
                            "mark at least one input on that cycle mode: delayed.")


def robot_start(params: dict[int, BaseModel]) -> dict[str, float] | None:
    """The robot's start pose: the ``start`` parameter (x, y, yaw) that a node of the
    scenario sets (the physics node's), or None when none does."""
    for i in sorted(params):
        start = getattr(params[i], "start", None)
        if start is not None and hasattr(start, "x") and hasattr(start, "y"):
            return {"x": float(start.x), "y": float(start.y),
                    "yaw": float(getattr(start, "yaw", 0.0))}
    return None


def _rates_that_fit(period_ns: Ns, tick_ns: Ns, gcd_of_periods: Ns) -> str:
    """Rates near the given period whose period is a whole number of ticks, written exactly."""
    fits = []
    for m in range(1, 100_000):
        rate = Fraction(NS_PER_S, m * tick_ns)
        if _is_decimal(rate):
            fits.append(m * tick_ns)
        above_count = len([p for p in fits if p > period_ns])
        if m * tick_ns > period_ns and (above_count >= 2 or m * tick_ns > 1000 * period_ns):
            break
    below = [p for p in fits if p < period_ns][-2:]
    above = [p for p in fits if p > period_ns][:2]
    if not below + above:
        return (f"no rate in Hz has a period that is a whole number of {format_ns(tick_ns)} "
                f"ticks; change the tick, e.g. leave tick out to use the gcd of the periods "
                f"({format_ns(gcd_of_periods)}).")
    shown = ", ".join(exact_rate_text(Fraction(NS_PER_S, p)) for p in sorted(below + above))
    return f"rates whose period is a multiple of the {format_ns(tick_ns)} tick, e.g. {shown} Hz."


def _is_decimal(value: Fraction) -> bool:
    """Whether a fraction can be written exactly as a decimal (denominator 2**a * 5**b)."""
    d = value.denominator
    for f in (2, 5):
        while d % f == 0:
            d //= f
    return d == 1
