"""Physics wired to a robot's controller manager by the plan, not by the scenario's remaps.

A node class with ``hardware_role`` (the controller manager) stands between the physics
node and the robot's hardware: it reads the joints on ``/cosim/hardware_states`` and writes
the joint commands on ``/cosim/hardware_commands`` and the base's twist on
``/cosim/base_command``, which are physics' ``/joint_states``, ``/joint_commands`` and
``/cmd_vel`` of that robot. The scenario names none of them; the plan connects the two ends
one of two ways, chosen by the manager's own topics:

- **The controllers are the robot's face.** When the manager publishes or takes one of the
  robot's topics itself (``/joint_states`` from a joint state broadcaster, ``/joint_commands``
  where a forward controller's commands are remapped), physics' robot topics move to the
  hardware names, as ros2_control's hardware has no topics of its own. This needs physics
  remappable, so a scenario without a ``robots:`` section.
- **Physics is the robot's face.** Otherwise physics keeps its topics (``/joint_states``
  reaches ROS users from physics) and the manager reads and writes them: its hardware
  topics are remapped to the robot's (``/mybot/joint_states``, ``/mybot/cmd_vel`` for a
  ``for_each: robot`` manager).

A scenario that already wires a hardware topic by hand (a remap naming one) is left as it
is, so files written before this still run. ``robots.controllers`` adds the manager itself
(:func:`with_robot_managers`).
"""

from __future__ import annotations

from pathlib import Path

from plan.errors import ScenarioError, ScenarioNotice
from plan.kinds import catalogue, class_of
from plan.model import InputSpec, NodeSpec, ScenarioModel
from plan.topic_names import CMD_VEL, JOINT_COMMANDS, JOINT_STATES

HARDWARE_STATES = "/cosim/hardware_states"
HARDWARE_COMMANDS = "/cosim/hardware_commands"
BASE_COMMAND = "/cosim/base_command"
HARDWARE_OF = {JOINT_STATES: HARDWARE_STATES, JOINT_COMMANDS: HARDWARE_COMMANDS,
               CMD_VEL: BASE_COMMAND}
"""Physics' robot topic -> the hardware topic the controller manager knows it as."""
HARDWARE_TOPICS = frozenset(HARDWARE_OF.values())


def _topics(spec: NodeSpec, cls: type, scenario_dir: Path) -> tuple[set[str], set[str]] | None:
    """(every topic the node knows, its outputs and client-fed inputs) by its own names;
    None where its parameters are wrong (the checks report that)."""
    try:
        params = cls.Params.model_validate(spec.params, context={"scenario_dir": scenario_dir})
        outputs = set(cls.outputs(params)) | set(cls.latched_outputs(params))
        face = outputs | set(cls.client_inputs(params))
        known = face | set(cls.accepted_inputs(params) or ()) | {i.topic for i in spec.inputs}
    except Exception:  # noqa: BLE001 - reported by the scenario's checks with its key
        return None
    return known, face


def hand_wired(model: ScenarioModel) -> bool:
    """Whether a remap of the scenario already names a hardware topic (either side)."""
    return any(topic in HARDWARE_TOPICS for spec in model.nodes
               for pair in spec.remap.items() for topic in pair)


def hand_wiring_notices(path: Path, model: ScenarioModel) -> list[ScenarioNotice]:
    """A notice for each remap that names a hardware topic in a scenario with a controller
    manager: cosim wires them itself, so the remap (and the manager's listed
    ``/cosim/hardware_states`` input) may be deleted; ``--strict`` refuses them."""
    if not any(getattr(class_of(spec), "hardware_role", False) for spec in model.nodes):
        return []
    return [ScenarioNotice(path, f"nodes[{i}] ({spec.name}).remap.{own}", f"{own} -> {graph} "
                           "wires physics to the controller manager by hand; cosim wires "
                           "them itself (docs/concepts/topics.md, ros2_control).",
                           "delete the remaps naming /cosim/ topics, and the controller "
                           "manager's /cosim/hardware_states input.")
            for i, spec in enumerate(model.nodes) for own, graph in spec.remap.items()
            if own in HARDWARE_TOPICS or graph in HARDWARE_TOPICS]


def wire_hardware(path: Path, model: ScenarioModel, has_robots: bool) -> ScenarioModel:
    """The model with physics and every controller manager connected (module docstring):
    the remaps added to the physics node or to the managers, each manager's hardware state
    input (same tick) and physics' command inputs (delayed) listed where the scenario does
    not list them. ``has_robots``: the
    scenario has a ``robots:`` section (physics' topics are then not remappable)."""
    nodes = list(model.nodes)
    by_hand = hand_wired(model)
    classes = {i: class_of(spec) for i, spec in enumerate(nodes)}
    managers = [i for i, cls in classes.items() if getattr(cls, "hardware_role", False)]
    worlds = [i for i, cls in classes.items() if getattr(cls, "every_robot", False)]
    if not managers or len(worlds) != 1:
        return model
    physics = worlds[0]
    physics_topics = _topics(nodes[physics], classes[physics], path.parent)
    for i in managers:
        spec, topics = nodes[i], _topics(nodes[i], classes[i], path.parent)
        if topics is None or physics_topics is None:
            continue
        known, face = topics
        used = {robot: hw for robot, hw in HARDWARE_OF.items() if hw in known}
        taken = sorted({spec.remap.get(t, t) for t in face} & set(HARDWARE_OF))
        if by_hand:
            pass  # wired as before: only the state input is listed for it
        elif taken and (has_robots or spec.for_each is not None):
            raise ScenarioError(path, f"nodes[{i}] ({spec.name})", f"its controllers "
                                f"publish or take {taken[0]}, which physics serves for each "
                                "robot of the robots: section.", f"controllers that leave "
                                f"{taken[0]} to physics (it publishes /ROBOT/joint_states), "
                                "or a scenario without a robots: section.")
        elif taken:
            remap = {robot: hw for robot, hw in used.items() if robot in physics_topics[0]}
            nodes[physics] = _remapped(nodes[physics], remap)
        else:
            nodes[i] = _remapped(spec, {hw: robot for robot, hw in used.items()})
        if HARDWARE_STATES in known:
            nodes[i] = _with_input(nodes[i], HARDWARE_STATES, "same_tick", first=True)
        if not by_hand:  # physics takes the commands the manager writes, a tick later
            for robot, hw in used.items():
                if hw != HARDWARE_STATES and robot in physics_topics[0]:
                    nodes[physics] = _with_input(nodes[physics], robot, "delayed")
    return model.model_copy(update={"nodes": nodes})


def _with_input(spec: NodeSpec, topic: str, mode: str, first: bool = False) -> NodeSpec:
    """``spec`` taking ``topic`` (its own name) in ``mode``, first or last among its inputs,
    unless it lists that topic already."""
    if any(inp.topic == topic for inp in spec.inputs):
        return spec
    added = InputSpec(topic=topic, mode=mode)
    inputs = [added, *spec.inputs] if first else [*spec.inputs, added]
    return spec.model_copy(update={"inputs": inputs})


def _remapped(spec: NodeSpec, remap: dict[str, str]) -> NodeSpec:
    """``spec`` with ``remap`` added under its own remaps (a remap it has wins)."""
    return spec.model_copy(update={"remap": {**remap, **spec.remap}})


MANAGER_NAME = "controller_manager"


def hardware_kind() -> str | None:
    """The node kind that takes the hardware role (the controller manager), if any."""
    kinds = catalogue()
    for kind in kinds.listed:
        try:
            if getattr(kinds.load(kinds.kinds[kind]), "hardware_role", False):
                return kind
        except Exception:  # noqa: BLE001 - a kind that does not load is not this one
            continue
    return None


def with_robot_managers(path: Path, model: ScenarioModel) -> ScenarioModel:
    """The model with ``robots.controllers`` made a node: ``controller_manager``,
    ``for_each: robot``, at the file's update_rate, taking same tick each of its
    controllers' topics that a robot's node or physics publishes (by the node's own names,
    as templates' topics are the robot's). Exit 2 naming ``robots.controllers`` where the
    file is wrong or a node of the scenario already has the name."""
    robots = model.robots
    if robots is None or robots.controllers is None:
        return model
    key = "robots.controllers"
    if any(spec.name == MANAGER_NAME for spec in model.nodes):
        raise ScenarioError(path, key, f"the scenario also has a node named {MANAGER_NAME}.",
                            "robots.controllers, or that node (not both).")
    kind = hardware_kind()
    cls = class_of(NodeSpec(name=MANAGER_NAME, kind=kind, rate=1)) if kind else None
    if cls is None:
        raise ScenarioError(path, key, "no node kind runs a controller manager here.",
                            "leave robots.controllers out.")
    try:
        params = cls.Params.model_validate({"controllers": robots.controllers},
                                           context={"scenario_dir": path.parent})
        rate, fed = cls.natural_rate(params), set(cls.client_inputs(params))
    except Exception as exc:  # noqa: BLE001 - the controllers file's problem, said as it is
        text = _said(exc)
        raise ScenarioError(path, key, text, "" if "Accepted:" in text else "a ros2_control "
                            "controllers file, relative to this file.") from None
    published = set()
    for spec in model.nodes:
        other = class_of(spec)
        if other is None or not (spec.for_each or getattr(other, "every_robot", False)):
            continue
        try:
            own = other.Params.model_validate(spec.params,
                                              context={"scenario_dir": path.parent})
            published |= {spec.remap.get(t, t) for t in other.outputs(own)}
        except Exception:  # noqa: BLE001 - reported by the scenario's checks with its key
            continue
    inputs = [InputSpec(topic=t, mode="same_tick") for t in sorted(fed & published)]
    manager = NodeSpec(name=MANAGER_NAME, kind=kind, rate=rate, for_each="robot",
                       params={"controllers": robots.controllers}, inputs=inputs)
    return model.model_copy(update={"nodes": [*model.nodes, manager]})


def _said(exc: Exception) -> str:
    """What a failed check of the controllers file says (a pydantic error's first message
    without pydantic's framing)."""
    errors = getattr(exc, "errors", None)
    if callable(errors):
        try:
            return str(errors()[0]["msg"]).removeprefix("Value error, ")
        except Exception:  # noqa: BLE001 - not pydantic's: its text as it is
            pass
    return str(exc).strip()
