"""The scenario model rewritten for a run: its ``external:`` section becomes a node named
'external' (stepped by the orchestrator), and in an interactive scenario every node gets
the inputs clients feed through it (plan/interactive.py)."""

from __future__ import annotations

from pathlib import Path

from plan.checks import ScenarioChecks
from plan.interactive import FED_INPUTS, PARAMS_TYPE, params_topic
from plan.kinds import catalogue
from plan.model import InputSpec, NodeSpec, ScenarioModel
from plan.robots import per_robot, robot_namespaces
from plan.scenario import EXTERNAL_NAME


def complete_model(path: Path, model: ScenarioModel) -> ScenarioModel:
    """The file's model checked for what needs no node class (finite values, unique names),
    then with its external node and fed inputs added: the model the run resolves."""
    where = ScenarioChecks(path, model)
    where.check_finite("", model.model_dump(by_alias=True, exclude={"nodes"}))
    where.check_unique_names()
    return with_external_node(where)


def with_external_node(where: ScenarioChecks) -> ScenarioModel:
    """The model with its ``external:`` section as a node named 'external' (last), and,
    when the scenario is interactive, the inputs clients feed through it
    (plan/interactive.py); without a section, it runs at the fastest node's rate."""
    spec = where.model.external
    topics = dict(spec.topics) if spec else {}
    nodes = list(where.model.nodes)
    if where.model.interactive:
        nodes = [with_client_inputs(where, i, node, topics) for i, node in enumerate(nodes)]
    if not topics:
        return where.model
    for i, node in enumerate(where.model.nodes):
        if node.name == EXTERNAL_NAME:
            raise where.fail(where.node_key(i, "name"), f"the name {EXTERNAL_NAME!r} is "
                             "reserved for the node of the scenario's external: section.",
                             "another name.")
    period = spec.period_ns if spec else min(node.period_ns for node in nodes)
    node = NodeSpec.model_construct(
        name=EXTERNAL_NAME, kind=None, module=catalogue().external, period_ns=period,
        params={"topics": topics}, inputs=[], remap={},
        debug=NodeSpec.model_fields["debug"].default_factory(), command=None,
        external=False, prefix=None)
    return where.model.model_copy(update={"nodes": [*nodes, node]})


def with_client_inputs(where: ScenarioChecks, i: int, spec: NodeSpec, topics: dict[str, str]
                       ) -> NodeSpec:
    """Node ``i`` with the inputs clients feed (goal, teleport, parameter changes) that
    its class takes; adds their graph topics to the external node's ``topics``."""
    if spec.command is not None:
        return spec
    cls = where.node_class(i, spec)[1]
    accepted = cls.accepted_inputs(where.node_params(i, spec, cls))
    spaces = robot_namespaces(where.model.robots, spec.robots)
    accepted = per_robot(accepted, spaces) or set()
    wanted = {own: kind for own, kind in FED_INPUTS.items() if own in accepted}
    listed = {inp.topic for inp in spec.inputs}
    wanted.update({own: kind for own, kind in per_robot(cls.client_inputs(
        where.node_params(i, spec, cls)), spaces).items() if own not in listed})
    if cls.runtime_params:
        wanted[params_topic(spec.name)] = PARAMS_TYPE
    listed = {inp.topic for inp in spec.inputs}
    added = []
    for own, type_name in wanted.items():
        graph = spec.remap.get(own, own)
        if topics.setdefault(graph, type_name) != type_name:
            raise where.fail(f"external.topics.{graph}", f"{graph} carries {type_name} "
                             f"into node {spec.name!r} of this interactive scenario, not "
                             f"{topics[graph]}.", f"{type_name}, or leave the topic out.")
        if own not in listed:
            added.append(InputSpec(topic=own, mode="same_tick"))
    return spec.model_copy(update={"inputs": [*spec.inputs, *added]}) if added else spec
