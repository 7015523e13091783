"""How a scenario's nodes connect: each node's outputs under their graph names, the one
producer of every topic, and each input resolved to its producer with the types checked."""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

from pydantic import BaseModel

from plan.checks import ScenarioChecks
from plan.interactive import params_topic
from plan.model import NodeSpec
from plan.robots import per_robot, robot_namespaces
from plan.ros_types import ros_type
from plan.scenario import InputPlan


@dataclass(frozen=True)


class Producer:
    """Who publishes a graph topic, as the loader resolves inputs against it."""

    name: str
    index: int  # in the scenario's nodes list
    msg: type
    latched: bool
    type_key: str | None  # the producer's parameter that chooses the type, if any


def node_outputs(where: ScenarioChecks, i: int, spec: NodeSpec, cls: type, params: BaseModel
                 ) -> tuple[dict[str, type], dict[str, str], frozenset[str]]:
    """The node's outputs under graph names (after remap), own -> graph names, and the
    own names of its latched outputs (published once, at the first activation)."""
    spaces = robot_namespaces(where.model.robots, spec.robots)
    try:
        own = per_robot(cls.outputs(params), spaces)
        latched = per_robot(cls.latched_outputs(params), spaces)
    except Exception as exc:  # noqa: BLE001 - the node class's code: the user's to fix
        key = "module" if spec.module else "kind"
        what = ("does not implement outputs(params)" if isinstance(exc, NotImplementedError)
                else f"raised {type(exc).__name__} in outputs(params): {exc}")
        raise where.fail(where.node_key(i, key), f"{cls.__module__}.{cls.__qualname__} {what}.",
                         "a node class with the whole contract: outputs(params) returning "
                         "{topic: message class}, reset and step (see "
                         "docs/tutorials/own-node.md).") from None
    if missing := _not_implemented(cls, "step"):
        raise where.fail(where.node_key(i, "module" if spec.module else "kind"),
                         f"{cls.__module__}.{cls.__qualname__} {missing}.",
                         "a node class with the whole contract: outputs(params), reset and "
                         "step(tick, inputs) (see docs/tutorials/own-node.md).")
    if both := sorted(set(own) & set(latched)):
        raise where.fail(where.node_key(i), f"the node declares {both[0]} both as an output "
                         "of every activation and as a latched one.",
                         "each topic in one of outputs() and latched_outputs().")
    own = {**own, **latched}
    accepted = per_robot(cls.accepted_inputs(params),
                         robot_namespaces(where.model.robots, spec.robots))
    known = set(own) | {inp.topic for inp in spec.inputs} | (accepted or set())
    for source in spec.remap:
        if source not in known:
            raise where.fail(where.node_key(i, f"remap.{source}"),
                             f"the node has no topic {source!r} to remap.",
                             f"one of its topics: {', '.join(sorted(known)) or 'none'}.")
    names = {t: spec.remap.get(t, t) for t in own}
    graph_names: dict[str, str] = {}
    for t, graph in names.items():
        if graph in graph_names:
            raise where.fail(where.node_key(i, "remap"), f"outputs {graph_names[graph]} and "
                             f"{t} would both be published as {graph}.",
                             "a distinct graph name for each output.")
        graph_names[graph] = t
    return {names[t]: msg for t, msg in own.items()}, names, frozenset(latched)


def producers(where: ScenarioChecks, outputs: dict[int, tuple[dict[str, type], dict, frozenset]],
              classes: dict[int, type]) -> dict[str, Producer]:
    """graph topic -> its Producer; a topic has one publisher."""
    found: dict[str, Producer] = {}
    for i, (topics, names, latched) in outputs.items():
        own_of = {graph: own for own, graph in names.items()}
        for topic, msg in topics.items():
            if topic in found:
                raise where.fail(where.node_key(i), f"topic {topic} is also published by node "
                                 f"{found[topic].name!r}.", "one publisher per topic; "
                                 "rename one with remap.")
            own = own_of[topic]
            found[topic] = Producer(where.model.nodes[i].name, i, msg, own in latched,
                                    classes[i].type_keys.get(own))
    return found


def node_inputs(where: ScenarioChecks, i: int, spec: NodeSpec, cls: type, params: BaseModel,
                publishers: dict[str, Producer]) -> list[InputPlan]:
    """The node's inputs resolved to producers; every input needs a publisher. The
    problems of each input are kept in ``where.found`` (the input left out), so that all
    of them are reported."""
    spaces = robot_namespaces(where.model.robots, spec.robots)
    accepted = per_robot(cls.accepted_inputs(params), spaces)

    # a world node's types under every robot's namespace: made once, not once per robot's
    # input (a million entries at a thousand robots); made at the first input that asks, so
    # that what input_types raises is that input's problem
    @functools.cache
    def types() -> dict[str, type] | None:
        return per_robot(cls.input_types(params), spaces)

    plans, seen = [], set()
    for j in range(len(spec.inputs)):
        with where.found.collecting():
            plans.append(_input_plan(where, i, j, spec, cls, params, publishers, accepted,
                                     seen, types))
    return plans


def _input_plan(where: ScenarioChecks, i: int, j: int, spec: NodeSpec, cls: type,
                params: BaseModel, publishers: dict[str, Producer], accepted: set[str] | None,
                seen: set[str], types: Callable[[], dict[str, type] | None]) -> InputPlan:
    """Input ``j`` of node ``i`` resolved to its producer, or the ScenarioError saying why
    it cannot be; ``types``: the node's input types under its robots' namespaces."""
    inp = spec.inputs[j]
    key = where.node_key(i, f"inputs[{j}].topic")
    if inp.topic in seen:
        raise where.fail(key, f"input {inp.topic} is listed twice.", "each topic once.")
    seen.add(inp.topic)
    takes_params = cls.runtime_params and inp.topic == params_topic(spec.name)
    if accepted is not None and inp.topic not in accepted and not takes_params:
        raise where.fail(key, f"this node does not take {inp.topic}.",
                         f"one of {', '.join(sorted(accepted))}.")
    graph = spec.remap.get(inp.topic, inp.topic)
    if graph not in publishers:
        raise where.fail(key, f"no node publishes {graph}.",
                         f"a published topic: {', '.join(sorted(publishers))}.")
    source = publishers[graph]
    if source.latched:
        raise where.fail(key, f"{graph} is published once, latched, by node "
                         f"{source.name!r} at its first activation; no tick's sample "
                         "of it can be scheduled.", "a topic published at every "
                         "activation (ROS tools and foreign programs read a latched "
                         "topic with transient-local durability).")
    check_input_type(where, i, inp.topic, cls, graph, source, types())
    return InputPlan(inp.topic, graph, source.name, inp.mode, source.msg)


def check_input_type(where: ScenarioChecks, i: int, topic: str, cls: type, graph: str,
                     source: Producer, types: dict[str, type] | None) -> None:
    """The producer publishes the message type this node takes on ``topic`` (when it
    says which: ``types``, the node's ``input_types`` under its robots' namespaces for a
    world node), or the error names the parameter that sets this node's type."""
    wanted = (types or {}).get(topic)
    if wanted is None or source.msg is wanted:
        return
    own_key = cls.type_keys.get(topic)
    key = where.node_key(i, own_key) if own_key else where.node_key(i, "inputs")
    producer = where.node_key(source.index)
    theirs = (f"{producer}.{source.type_key}" if source.type_key
              else f"the type {producer} publishes it as")
    ours = f"this node's {own_key}" if own_key else "this node's input"
    raise where.fail(key, f"this node takes {topic} as {ros_type(wanted)}, but node "
                     f"{source.name!r} publishes {graph} as {ros_type(source.msg)}.",
                     f"the same message type at both ends: change {ours} or {theirs}.")


def _not_implemented(cls: type, method: str) -> str | None:
    """'does not implement step(...)' when ``cls`` takes ``method`` from the root of its
    node classes (the contract's base, whose own raises NotImplementedError), else None."""
    owners = [c for c in cls.__mro__ if method in vars(c)]
    if len(owners) >= 1 and owners[0] is owners[-1] and owners[0] is not cls:
        return f"does not implement {method}(tick, inputs)"
    return None
