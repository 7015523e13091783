"""Node templates: a node with ``for_each: robot`` becomes one node per robot, its topics in
the robot's namespace (a lone robot's at the root), and the world node (physics) gets every
robot's name (its spec's ``robots``) and one input per robot (plan/robots.py)."""

from __future__ import annotations

from pathlib import Path

from plan.errors import ScenarioError
from plan.kinds import class_of
from plan.model import InputSpec, NodeSpec, ScenarioModel
from plan.robots import RobotsLayout, namespaced


def expand_nodes(path: Path, model: ScenarioModel, layout: RobotsLayout | None
                 ) -> tuple[ScenarioModel, dict[str, int]]:
    """The model with every ``for_each: robot`` node replaced by one instance per robot
    (``NAME@ROBOT``, every topic under the robot's namespace) and the world node (a class
    with ``every_robot``) given every robot's name and one input per robot. Also returns each
    node's index in the file, by name (an instance's is its template's)."""
    nodes: list[NodeSpec] = []
    origins: dict[str, int] = {}
    for i, spec in enumerate(model.nodes):
        key = f"nodes[{i}] ({spec.name})"
        if spec.for_each is None:
            if spec.robots is not None:
                raise ScenarioError(path, f"{key}.robots", "robots: chooses the robots of a "
                                    "template.", "for_each: robot with it, or leave robots out.")
            nodes.append(_world_node(spec, layout) if layout else spec)
            origins[spec.name] = i
            continue
        if layout is None:
            raise ScenarioError(path, f"{key}.for_each", "the scenario has no robots: section.",
                                "a robots: section, or leave for_each out.")
        cls = class_of(spec)
        if cls is not None and getattr(cls, "every_robot", False):
            what = f"kind {spec.kind}" if spec.kind else spec.module
            raise ScenarioError(path, f"{key}.for_each", f"{spec.name} ({what}) steps one world "
                                "for every robot, so it cannot be templated per robot.",
                                "leave for_each out: one such node simulates every robot of "
                                "the robots: section, each robot's topics under /ROBOT/.")
        chosen = spec.robots or layout.names
        for j, robot in enumerate(chosen):
            if robot not in layout.names:
                raise ScenarioError(path, f"{key}.robots[{j}]", f"there is no robot {robot!r}.",
                                    f"one of {', '.join(layout.names[:8])}"
                                    f"{', ...' if len(layout.names) > 8 else ''}.")
        nodes += [_instance(spec, robot, layout.namespace_of(robot), path.parent)
                  for robot in chosen]
        origins.update({f"{spec.name}@{robot}": i for robot in chosen})
    return model.model_copy(update={"nodes": nodes}), origins


def _instance(spec: NodeSpec, robot: str, namespace: str, scenario_dir: Path) -> NodeSpec:
    cls = class_of(spec)
    params = dict(spec.params)
    own = {inp.topic for inp in spec.inputs}
    if cls is not None:
        try:
            checked = cls.Params.model_validate(params,
                                                context={"scenario_dir": scenario_dir})
            own |= set(cls.outputs(checked)) | set(cls.latched_outputs(checked))
            # what clients feed it (a controller manager's switches, a controller's goals)
            # is the robot's too: /robot_2/controller_manager/..., as a namespaced node's
            own |= set(cls.client_inputs(checked))
        except Exception:  # noqa: BLE001 - reported by the scenario's checks with its key
            pass
    remap = {topic: namespaced(namespace, spec.remap.get(topic, topic)) for topic in own}
    remap.update({topic: namespaced(namespace, graph) for topic, graph in spec.remap.items()})
    remap = {topic: graph for topic, graph in remap.items() if graph != topic}
    command = spec.command
    if command is not None and namespace:
        command = [*command, "--ros-args", "-r", f"__ns:=/{namespace}"]
    return spec.model_copy(update={"name": f"{spec.name}@{robot}", "params": params,
                                   "remap": remap, "command": command, "for_each": None,
                                   "robots": None})


def _world_node(spec: NodeSpec, layout: RobotsLayout) -> NodeSpec:
    cls = class_of(spec)
    if cls is None or not getattr(cls, "every_robot", False):
        return spec
    inputs: list[InputSpec] = []
    for inp in spec.inputs:
        graph = spec.remap.get(inp.topic, inp.topic)
        if namespaced("r", graph) == graph:
            inputs.append(inp)
        else:
            inputs += [InputSpec(topic=namespaced(layout.namespace_of(r), graph),
                                 mode=inp.mode) for r in layout.names]
    return spec.model_copy(update={"robots": layout.names, "inputs": inputs, "remap": {}})
