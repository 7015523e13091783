"""Load a scenario file, check it completely, and resolve it into a runnable plan.

Everything that can be wrong with a scenario is found here, before any process starts,
and reported as a ``ScenarioError`` naming the file, the key path and what is accepted.
"""

from __future__ import annotations

import copy
import hashlib
import math
import shlex
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path
from typing import Any

import yaml
from pydantic import BaseModel, ValidationError

from plan.errors import ScenarioError, ScenarioNotice
from plan.interactive import FED_INPUTS, PARAMS_TYPE, params_topic
from plan.kinds import catalogue
from plan.model import InputSpec, NodeSpec, ScenarioModel
from plan.schedule import Edge, Schedule, find_same_tick_cycle
from plan.timeutil import NS_PER_S, exact_rate_text, format_ns, format_rate
from plan.validation import describe_validation_error, key_path

EXTERNAL_NAME = "external"  # the node that the scenario's external: section becomes


@dataclass(frozen=True)
class InputPlan:
    """A resolved input: the node's own topic name, the graph topic, its producer and type."""

    topic: str
    graph_topic: str
    producer: str
    mode: str
    msg_type: type


@dataclass(frozen=True)
class NodePlan:
    """A resolved node: its class, checked parameters, period and remapped topics."""

    name: str
    spec: NodeSpec
    class_ref: str
    params: BaseModel
    period_ticks: int
    outputs: dict[str, type]  # graph topic -> message class (latched ones included)
    output_names: dict[str, str]  # node's own topic -> graph topic
    inputs: list[InputPlan]
    latched: frozenset[str] = frozenset()  # own names of the outputs published once, latched

    @property
    def latched_topics(self) -> frozenset[str]:
        """Graph names of the outputs published once, at the first activation, latched."""
        return frozenset(self.output_names[own] for own in self.latched)

    @property
    def declared_outputs(self) -> dict[str, type]:
        """The node's own output topic names -> message classes (before remap)."""
        return {own: self.outputs[graph] for own, graph in self.output_names.items()}

    @property
    def launch_prefix(self) -> list[str]:
        """The command that wraps the node's process (scenario key ``prefix``), split."""
        return shlex.split(self.spec.prefix) if self.spec.prefix else []

    @property
    def in_orchestrator(self) -> bool:
        """Whether the orchestrator steps this node itself (the external node): no process."""
        return self.class_ref == catalogue().external

    @property
    def foreign(self) -> bool:
        """Whether this node is a foreign ROS 2 program started from a command."""
        return self.spec.command is not None


@dataclass(frozen=True)
class Producer:
    """Who publishes a graph topic, as the loader resolves inputs against it."""

    name: str
    index: int  # in the scenario's nodes list
    msg: type
    latched: bool
    type_key: str | None  # the producer's parameter that chooses the type, if any


def ros_type(msg_class: type) -> str:
    """'geometry_msgs/msg/Twist' for an rclpy message class."""
    return f"{msg_class.__module__.split('.')[0]}/msg/{msg_class.__name__}"


@dataclass
class Scenario:
    """A checked scenario: the model, its file, tick, nodes in file order and the schedule."""

    file: Path
    model: ScenarioModel
    tick_ns: int
    nodes: dict[str, NodePlan]
    schedule: Schedule
    world: Path | None
    sha256: str
    overrides: dict[str, Any] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)  # ScenarioNotice texts

    @property
    def name(self) -> str:
        """The scenario's name."""
        return self.model.name

    @property
    def topics(self) -> dict[str, type]:
        """Every published graph topic and its message class."""
        out: dict[str, type] = {}
        for plan in self.nodes.values():
            out.update(plan.outputs)
        return out

    @property
    def latched_topics(self) -> frozenset[str]:
        """Graph topics published once per run, latched (transient-local), e.g. /tf_static."""
        return frozenset(t for plan in self.nodes.values() for t in plan.latched_topics)

    @property
    def trailing_nodes(self) -> frozenset[str]:
        """The nodes that may trail the others by up to one activation: leaves of the graph
        (nothing consumes their outputs), not foreign. Their metrics never decide an early
        stop, on any driver."""
        return frozenset(n for n in self.schedule.leaves() if not self.nodes[n].foreign)

    def producer_of(self, topic: str) -> str:
        """The node that publishes a graph topic."""
        for plan in self.nodes.values():
            if topic in plan.outputs:
                return plan.name
        raise KeyError(topic)


def load_scenario(path: str | Path, overrides: dict[str, Any] | None = None) -> Scenario:
    """Read, check and resolve a scenario file; raise ScenarioError on anything wrong.

    ``overrides`` maps dotted keys ('seed', 'nodes.<node name>.rate') to values that replace
    the file's before anything is checked; an error in an overridden value says so.
    """
    path = Path(path)
    raw, text = _read_yaml(path)
    overrides = dict(overrides or {})
    overridden = {key: _apply_override(raw, key, value, path) for key, value in overrides.items()}
    try:
        try:
            model = ScenarioModel.model_validate(raw)
        except ValidationError as exc:
            key, problem, accepted = describe_validation_error(exc, raw)
            raise ScenarioError(path, key, problem, accepted) from None
        return _resolve(path, model, hashlib.sha256(text).hexdigest(), overrides)
    except ScenarioError as exc:
        raise _blame_override(exc, raw, overridden, overrides) from None


def _blame_override(exc: ScenarioError, raw: dict, overridden: dict[str, tuple],
                    overrides: dict[str, Any]) -> ScenarioError:
    """Add which override set the value to an error about an overridden key."""
    for key, loc in overridden.items():
        shown = key_path(loc, raw)
        if _within(exc.key, shown) or _within(shown, exc.key):
            return ScenarioError(exc.file, exc.key, f"{exc.problem} (The value comes from the "
                                 f"override {key}={overrides[key]!r}.)", exc.accepted)
    return exc


def _within(key: str, outer: str) -> bool:
    """Whether key path ``key`` is ``outer`` or inside it."""
    return bool(outer) and (key == outer or key.startswith((outer + ".", outer + "[")))


# libyaml's safe loader when PyYAML was built with it (10x faster; every process of a run
# parses the scenario), the pure-Python one otherwise: same documents, same errors.
_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
_YAML_STR = "tag:yaml.org,2002:str"
_YAML_MERGE = "tag:yaml.org,2002:merge"


def _read_yaml(path: Path) -> tuple[dict, bytes]:
    if not path.is_file():
        what = "is a directory, not a file" if path.is_dir() else "does not exist"
        raise ScenarioError(path, "", f"the scenario file {what}.",
                            "the path of a YAML scenario file, e.g. scenarios/nav.yaml.")
    text = path.read_bytes()
    try:
        root = yaml.compose(text, Loader=_LOADER)
        if root is not None:
            _check_yaml_keys(root, "", path, set())
        raw = yaml.load(text, Loader=_LOADER)  # noqa: S506 - a safe loader
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise ScenarioError(path, "", f"YAML syntax error{where}: {problem}.",
                            "valid YAML; check indentation and quoting there.") from None
    if raw is None:
        raise ScenarioError(path, "", "the file is empty.",
                            "a mapping with at least name, duration and nodes.")
    if not isinstance(raw, dict):
        raise ScenarioError(path, "", f"the top level is a {type(raw).__name__}, not a mapping.",
                            "a mapping with keys such as name, seed, duration, nodes.")
    return raw, text


def _check_yaml_keys(node: yaml.Node, where: str, path: Path, seen_nodes: set[int]) -> None:
    """Refuse what plain YAML loading would hide: repeated keys and keys that are not text."""
    if id(node) in seen_nodes:
        return
    seen_nodes.add(id(node))
    if isinstance(node, yaml.MappingNode):
        lines: dict[str, int] = {}
        for key_node, value_node in node.value:
            if key_node.tag == _YAML_MERGE:
                continue
            line = key_node.start_mark.line + 1
            shown = key_node.value if isinstance(key_node, yaml.ScalarNode) else "?"
            key = f"{where}.{shown}" if where else str(shown)
            if not isinstance(key_node, yaml.ScalarNode) or key_node.tag != _YAML_STR:
                raise ScenarioError(path, key, f"the key {shown!r} at line {line} is not text "
                                    f"(YAML reads it as {key_node.tag.rsplit(':', 1)[-1]}).",
                                    f"a text key; quote it, e.g. '{shown}':")
            if shown in lines:
                raise ScenarioError(path, key, f"the key {shown!r} appears twice, at lines "
                                    f"{lines[shown]} and {line}.", "each key once per mapping.")
            lines[shown] = line
            _check_yaml_keys(value_node, key, path, seen_nodes)
    elif isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            label = f"{where}[{i}]"
            if isinstance(item, yaml.MappingNode):
                names = [v.value for k, v in item.value
                         if isinstance(k, yaml.ScalarNode) and k.value == "name"
                         and isinstance(v, yaml.ScalarNode) and v.tag == _YAML_STR]
                label += f" ({names[0]})" if names else ""
            _check_yaml_keys(item, label, path, seen_nodes)


def _apply_override(raw: dict, key: str, value: Any, path: Path) -> tuple:
    """Set a dotted key ('seed', 'nodes.control.params.max_speed') in the raw scenario.

    A part that meets a list names a node (or is an index). Returns the key's location
    as a pydantic-style tuple, e.g. ('nodes', 1, 'rate').
    """
    parts = key.split(".") if isinstance(key, str) else [""]
    accepted = "a dotted key such as 'seed', 'duration' or 'nodes.<node name>.rate'."
    if not all(parts):
        raise ScenarioError(path, "", f"the override {key!r} is not a dotted key path.", accepted)
    target: Any = raw
    loc: list = []
    for i, part in enumerate(parts):
        last = i == len(parts) - 1
        if isinstance(target, list):
            index = _node_index(target, part)
            if index is None:
                names = [n["name"] for n in target if isinstance(n, dict) and "name" in n]
                raise ScenarioError(path, key, f"override names no node {part!r}.",
                                    f"a node name: {', '.join(map(str, names)) or 'none'}.")
            loc.append(index)
            if last:
                target[index] = copy.deepcopy(value)
            target = target[index]
            continue
        if not isinstance(target, dict):
            through = ".".join(parts[:i])
            raise ScenarioError(path, key, f"override goes through {through}, which is "
                                f"{type(target).__name__}, not a mapping.", accepted)
        loc.append(part)
        if last:
            target[part] = copy.deepcopy(value)
        else:
            target = target.setdefault(part, {})
    return tuple(loc)


def _node_index(nodes: list, part: str) -> int | None:
    """The index of the node named ``part`` (or given by its index) in a raw nodes list."""
    for i, node in enumerate(nodes):
        if isinstance(node, dict) and node.get("name") == part:
            return i
    if part.isdigit() and int(part) < len(nodes):
        return int(part)
    return None


def _resolve(path: Path, model: ScenarioModel, sha: str, overrides: dict) -> Scenario:
    where = ScenarioContext(path, model)
    where.check_finite("", model.model_dump(by_alias=True, exclude={"nodes"}))
    where.check_unique_names()
    model = where.with_external_node()
    where = ScenarioContext(path, model)
    classes = {i: where.node_class(i, spec) for i, spec in enumerate(model.nodes)}
    params = {i: where.node_params(i, spec, classes[i][1]) for i, spec in enumerate(model.nodes)}
    for i in range(len(model.nodes)):
        where.check_finite(where.node_key(i, "params"), params[i].model_dump())
    world, world_model = where.world_path(any(cls.needs_world for _, cls in classes.values()))
    world_warnings = []
    if world_model is not None:
        world_warnings = where.check_world_fit(classes, params, world_model)
    tick_ns = where.tick_ns()
    last_tick = where.last_tick(tick_ns)
    outputs = {i: where.node_outputs(i, spec, classes[i][1], params[i])
               for i, spec in enumerate(model.nodes)}
    producers = where.producers(outputs, {i: cls for i, (_, cls) in classes.items()})
    nodes: dict[str, NodePlan] = {}
    edges: list[Edge] = []
    for i, spec in enumerate(model.nodes):
        inputs = where.node_inputs(i, spec, classes[i][1], params[i], producers)
        edges += [Edge(spec.name, inp.producer, inp.graph_topic, inp.mode) for inp in inputs]
        nodes[spec.name] = NodePlan(
            name=spec.name, spec=spec, class_ref=classes[i][0], params=params[i],
            period_ticks=spec.period_ns // tick_ns, outputs=outputs[i][0],
            output_names=outputs[i][1], inputs=inputs, latched=outputs[i][2])
    where.check_cycles(edges)
    schedule = Schedule(tick_ns, last_tick, {n: p.period_ticks for n, p in nodes.items()}, edges)
    where.check_foreign_counts(nodes, edges)
    warnings = world_warnings + unconsumed_remaps(path, nodes, edges)
    return Scenario(path, model, tick_ns, nodes, schedule, world, sha, overrides, warnings)


def unconsumed_remaps(path: Path, nodes: dict[str, NodePlan], edges: list[Edge]) -> list[str]:
    """Warnings for outputs remapped to a name no node consumes (allowed: ROS tools see it)."""
    consumed = {e.topic for e in edges}
    return [ScenarioNotice(path, f"nodes ({plan.name}).remap.{own}", f"{graph} is published "
                          "but no node of the scenario consumes it (only ROS tools will see "
                          "it).", "a remap to a topic a node of the scenario consumes.")
            for plan in nodes.values() for own, graph in plan.output_names.items()
            if own != graph and graph not in consumed]


def robot_start(params: dict[int, BaseModel]) -> dict[str, float] | None:
    """The robot's start pose: the ``start`` parameter (x, y, yaw) that a node of the
    scenario sets (the physics node's), or None when none does."""
    for i in sorted(params):
        start = getattr(params[i], "start", None)
        if start is not None and hasattr(start, "x") and hasattr(start, "y"):
            return {"x": float(start.x), "y": float(start.y),
                    "yaw": float(getattr(start, "yaw", 0.0))}
    return None


class ScenarioContext:
    """The semantic checks that follow schema validation, each raising a precise ScenarioError."""

    def __init__(self, path: Path, model: ScenarioModel):
        self.path = path
        self.model = model

    def fail(self, key: str, problem: str, accepted: str = "") -> ScenarioError:
        """Build the error for this file."""
        return ScenarioError(self.path, key, problem, accepted)

    def node_key(self, i: int, sub: str = "") -> str:
        """'nodes[1] (sensors).rate'-style key path."""
        key = f"nodes[{i}] ({self.model.nodes[i].name})"
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

    def with_external_node(self) -> ScenarioModel:
        """The model with its ``external:`` section as a node named 'external' (last), and,
        when the scenario is interactive, the inputs clients feed through it
        (plan/interactive.py); without a section, it runs at the fastest node's rate."""
        spec = self.model.external
        topics = dict(spec.topics) if spec else {}
        nodes = list(self.model.nodes)
        if self.model.interactive:
            nodes = [self.with_client_inputs(i, node, topics) for i, node in enumerate(nodes)]
        if not topics:
            return self.model
        for i, node in enumerate(self.model.nodes):
            if node.name == EXTERNAL_NAME:
                raise self.fail(self.node_key(i, "name"), f"the name {EXTERNAL_NAME!r} is "
                                "reserved for the node of the scenario's external: section.",
                                "another name.")
        period = spec.period_ns if spec else min(node.period_ns for node in nodes)
        node = NodeSpec.model_construct(
            name=EXTERNAL_NAME, kind=None, module=catalogue().external, period_ns=period,
            params={"topics": topics}, inputs=[], remap={},
            debug=NodeSpec.model_fields["debug"].default_factory(), command=None,
            external=False, prefix=None)
        return self.model.model_copy(update={"nodes": [*nodes, node]})

    def with_client_inputs(self, i: int, spec: NodeSpec, topics: dict[str, str]) -> NodeSpec:
        """Node ``i`` with the inputs clients feed (goal, teleport, parameter changes) that
        its class takes; adds their graph topics to the external node's ``topics``."""
        if spec.command is not None:
            return spec
        cls = self.node_class(i, spec)[1]
        accepted = cls.accepted_inputs(self.node_params(i, spec, cls)) or set()
        wanted = {own: kind for own, kind in FED_INPUTS.items() if own in accepted}
        if cls.runtime_params:
            wanted[params_topic(spec.name)] = PARAMS_TYPE
        listed = {inp.topic for inp in spec.inputs}
        added = []
        for own, type_name in wanted.items():
            graph = spec.remap.get(own, own)
            if topics.setdefault(graph, type_name) != type_name:
                raise self.fail(f"external.topics.{graph}", f"{graph} carries {type_name} "
                                f"into node {spec.name!r} of this interactive scenario, not "
                                f"{topics[graph]}.", f"{type_name}, or leave the topic out.")
            if own not in listed:
                added.append(InputSpec(topic=own, mode="same_tick"))
        return spec.model_copy(update={"inputs": [*spec.inputs, *added]}) if added else spec

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
                            f"kind: one of {', '.join(sorted(kinds.kinds))}; "
                            "or module: 'package.module:Class'; or command: [program, args...] "
                            "for a foreign ROS 2 program.")
        if spec.command is not None:
            return kinds.foreign, kinds.load(kinds.foreign)
        if spec.kind is not None:
            if spec.kind not in kinds.kinds:
                raise self.fail(self.node_key(i, "kind"), f"unknown node kind {spec.kind!r}.",
                                f"one of {', '.join(sorted(kinds.kinds))}.")
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
            return cls.Params.model_validate(spec.params)
        except ValidationError as exc:
            key, problem, accepted = describe_validation_error(exc, spec.params, cls.Params)
            raise self.fail(self.node_key(i, f"params.{key}" if key else "params"),
                            problem, accepted) from None

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

    def check_world_fit(self, classes: dict, params: dict, world_model) -> list[str]:
        """Each node's own check of the world (its robot there, start and goal placeable):
        problems raise; what only deserves a word (a goal its map cannot reach) is
        returned as warnings."""
        goal = self.model.goal.model_dump() if self.model.goal else None
        for i, (_, cls) in classes.items():
            if not cls.needs_world or not hasattr(cls, "world_problems"):
                continue
            for key, problem, accepted in cls.world_problems(params[i], world_model, goal):
                where = key if key.startswith("goal") else self.node_key(i, key)
                raise self.fail(where, f"{problem} (world {self.model.world})", accepted)
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

    def check_world(self, world: Path):
        """Load the world once here, so a file MuJoCo cannot load fails before any node starts."""
        from plan.worldfile import WorldError, check_world

        try:
            return check_world(world)
        except WorldError as exc:
            raise self.fail("world", f"{exc}", "an MJCF (.xml) or USD (.usda, .usdc, .usd) "
                            "world that MuJoCo loads; USD colliders must be Cube, Sphere, "
                            "Cylinder, Capsule, Z-axis Plane or Mesh prims.") from None

    def tick_ns(self) -> int:
        """The tick: given, or the gcd of all node periods; every period a whole number of ticks."""
        periods = [spec.period_ns for spec in self.model.nodes]
        tick = self.model.tick or math.gcd(*periods)
        for i, spec in enumerate(self.model.nodes):
            if spec.period_ns % tick:
                raise self.fail(self.node_key(i, "rate"),
                                f"a rate of {format_rate(spec.period_ns)} Hz has a period of "
                                f"{format_ns(spec.period_ns)}, not a whole number of "
                                f"{format_ns(tick)} ticks.", _rates_that_fit(spec.period_ns, tick,
                                                                 math.gcd(*periods)))
        return tick

    def last_tick(self, tick_ns: int) -> int:
        """The index of the last tick; the duration must be a whole number of ticks."""
        if self.model.duration % tick_ns:
            raise self.fail("duration", f"{format_ns(self.model.duration)} is not a whole number "
                            f"of {format_ns(tick_ns)} ticks.", "a multiple of the tick, e.g. "
                            f"{format_ns((self.model.duration // tick_ns + 1) * tick_ns)}.")
        return self.model.duration // tick_ns

    def node_outputs(self, i: int, spec: NodeSpec, cls: type, params: BaseModel
                     ) -> tuple[dict[str, type], dict[str, str], frozenset[str]]:
        """The node's outputs under graph names (after remap), own -> graph names, and the
        own names of its latched outputs (published once, at the first activation)."""
        own = cls.outputs(params)
        latched = cls.latched_outputs(params)
        if both := sorted(set(own) & set(latched)):
            raise self.fail(self.node_key(i), f"the node declares {both[0]} both as an output "
                            "of every activation and as a latched one.",
                            "each topic in one of outputs() and latched_outputs().")
        own = {**own, **latched}
        accepted = cls.accepted_inputs(params)
        known = set(own) | {inp.topic for inp in spec.inputs} | (accepted or set())
        for source in spec.remap:
            if source not in known:
                raise self.fail(self.node_key(i, f"remap.{source}"),
                                f"the node has no topic {source!r} to remap.",
                                f"one of its topics: {', '.join(sorted(known)) or 'none'}.")
        names = {t: spec.remap.get(t, t) for t in own}
        graph_names: dict[str, str] = {}
        for t, graph in names.items():
            if graph in graph_names:
                raise self.fail(self.node_key(i, "remap"), f"outputs {graph_names[graph]} and "
                                f"{t} would both be published as {graph}.",
                                "a distinct graph name for each output.")
            graph_names[graph] = t
        return {names[t]: msg for t, msg in own.items()}, names, frozenset(latched)

    def producers(self, outputs: dict[int, tuple[dict[str, type], dict, frozenset]],
                  classes: dict[int, type]) -> dict[str, Producer]:
        """graph topic -> its Producer; a topic has one publisher."""
        producers: dict[str, Producer] = {}
        for i, (topics, names, latched) in outputs.items():
            own_of = {graph: own for own, graph in names.items()}
            for topic, msg in topics.items():
                if topic in producers:
                    raise self.fail(self.node_key(i), f"topic {topic} is also published by node "
                                    f"{producers[topic].name!r}.", "one publisher per topic; "
                                    "rename one with remap.")
                own = own_of[topic]
                producers[topic] = Producer(self.model.nodes[i].name, i, msg, own in latched,
                                            classes[i].type_keys.get(own))
        return producers

    def node_inputs(self, i: int, spec: NodeSpec, cls: type, params: BaseModel,
                    producers: dict[str, Producer]) -> list[InputPlan]:
        """The node's inputs resolved to producers; every input needs a publisher."""
        accepted = cls.accepted_inputs(params)
        plans, seen = [], set()
        for j, inp in enumerate(spec.inputs):
            key = self.node_key(i, f"inputs[{j}].topic")
            if inp.topic in seen:
                raise self.fail(key, f"input {inp.topic} is listed twice.", "each topic once.")
            seen.add(inp.topic)
            takes_params = cls.runtime_params and inp.topic == params_topic(spec.name)
            if accepted is not None and inp.topic not in accepted and not takes_params:
                raise self.fail(key, f"this node does not take {inp.topic}.",
                                f"one of {', '.join(sorted(accepted))}.")
            graph = spec.remap.get(inp.topic, inp.topic)
            if graph not in producers:
                raise self.fail(key, f"no node publishes {graph}.",
                                f"a published topic: {', '.join(sorted(producers))}.")
            source = producers[graph]
            if source.latched:
                raise self.fail(key, f"{graph} is published once, latched, by node "
                                f"{source.name!r} at its first activation; no tick's sample "
                                "of it can be scheduled.", "a topic published at every "
                                "activation (ROS tools and foreign programs read a latched "
                                "topic with transient-local durability).")
            self.check_input_type(i, inp.topic, cls, params, graph, source)
            plans.append(InputPlan(inp.topic, graph, source.name, inp.mode, source.msg))
        return plans

    def check_input_type(self, i: int, topic: str, cls: type, params: BaseModel, graph: str,
                         source: Producer) -> None:
        """The producer publishes the message type this node takes on ``topic`` (when it
        says which), or the error names the parameter that sets this node's type."""
        wanted = cls.input_types(params).get(topic)
        if wanted is None or source.msg is wanted:
            return
        own_key = cls.type_keys.get(topic)
        key = self.node_key(i, own_key) if own_key else self.node_key(i, "inputs")
        producer = self.node_key(source.index)
        theirs = (f"{producer}.{source.type_key}" if source.type_key
                  else f"the type {producer} publishes it as")
        ours = f"this node's {own_key}" if own_key else "this node's input"
        raise self.fail(key, f"this node takes {topic} as {ros_type(wanted)}, but node "
                        f"{source.name!r} publishes {graph} as {ros_type(source.msg)}.",
                        f"the same message type at both ends: change {ours} or {theirs}.")

    def check_foreign_counts(self, nodes: dict[str, NodePlan], edges: list[Edge]) -> None:
        """A foreign output that cosim nodes consume must carry one message per activation."""
        consumed = {e.topic for e in edges}
        for i, spec in enumerate(self.model.nodes):
            plan = nodes[spec.name]
            if not plan.foreign:
                continue
            for own, graph in plan.output_names.items():
                if graph in consumed and plan.params.silent_at_start:
                    raise self.fail(self.node_key(i, "params.silent_at_start"),
                                    f"{graph} is consumed by other nodes, which need the "
                                    "program's sample of tick 0, and the program publishes "
                                    "nothing then.", "false, or no node consuming its outputs.")
                if graph in consumed and plan.params.count(own) != 1:
                    raise self.fail(self.node_key(i, f"params.per_activation.{own}"),
                                    f"{graph} is consumed by other nodes, which take one "
                                    f"message per activation, not {plan.params.count(own)}.",
                                    "1 for a consumed topic (or leave it out).")

    def check_cycles(self, edges: list[Edge]) -> None:
        """Refuse a cycle of same_tick edges, naming it."""
        cycle = find_same_tick_cycle([n.name for n in self.model.nodes], edges)
        if cycle:
            raise self.fail("nodes", f"the same_tick inputs form an algebraic loop "
                            f"{' -> '.join(cycle)} with no delay to break it.",
                            "mark at least one input on that cycle mode: delayed.")


def _rates_that_fit(period_ns: int, tick_ns: int, gcd_ns: int) -> str:
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
                f"({format_ns(gcd_ns)}).")
    shown = ", ".join(exact_rate_text(Fraction(NS_PER_S, p)) for p in sorted(below + above))
    return f"rates whose period is a multiple of the {format_ns(tick_ns)} tick, e.g. {shown} Hz."


def _is_decimal(value: Fraction) -> bool:
    """Whether a fraction can be written exactly as a decimal (denominator 2**a * 5**b)."""
    d = value.denominator
    for f in (2, 5):
        while d % f == 0:
            d //= f
    return d == 1
