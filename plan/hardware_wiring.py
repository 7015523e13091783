"""A robot's controller manager folded into the physics node by the plan.

A node class with ``hardware_role`` (the controller manager, kind ``ros2_control``) is
declared by the scenario (or added for every robot by ``robots.controllers``, or by the
``<parameters>`` of the description's gz_ros2_control plugin tag, :func:`with_robot_managers`)
and checked as a node of its own; then :func:`fold_managers`
takes it out of the node list and gives it to the physics node (its parameter
``controller_manager``), which runs it in its step over MjData, as mujoco_ros2_control's
system interface does (nodes/ros2_control/hosted.py). The manager's inputs (its
controllers' command topics and goals, the switch topic) become physics' inputs, delayed (a
controller takes at its update what arrived before it) but those clients feed at the tick;
its outputs are physics'. Physics' own ``/joint_commands`` and ``/cmd_vel`` give way to
controllers that command the joints and the wheels.

The manager runs at its controllers file's ``update_rate``, physics' rate / n for a whole n
(every n-th physics activation; its controllers' topics at that period, ``plan.schedule``).
Scenarios written for the manager as a node of its own wired physics to it with remaps to
``/cosim/hardware_states``, ``/cosim/hardware_commands`` and ``/cosim/base_command``: such
remaps and inputs are dropped, each with a notice (``--strict`` refuses them).
"""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

from plan.errors import ScenarioError, ScenarioNotice
from plan.kinds import catalogue, class_of
from plan.model import InputSpec, NodeSpec, ScenarioModel
from plan.robots import robot_of
from plan.scenario import EXTERNAL_NAME
from plan.timeutil import NS_PER_S, whole_divisions
from plan.topic_names import CMD_VEL, JOINT_COMMANDS

HARDWARE_STATES = "/cosim/hardware_states"
HARDWARE_COMMANDS = "/cosim/hardware_commands"
BASE_COMMAND = "/cosim/base_command"
HARDWARE_TOPICS = frozenset({HARDWARE_STATES, HARDWARE_COMMANDS, BASE_COMMAND})
"""The topics a separate controller manager and physics were once wired by (dropped)."""


def hand_wiring_notices(path: Path, model: ScenarioModel) -> list[ScenarioNotice]:
    """A notice for each remap or input that names a hardware topic in a scenario with a
    controller manager: the manager runs in the physics step, so they are dropped;
    ``--strict`` refuses them."""
    if not any(getattr(class_of(spec), "hardware_role", False) for spec in model.nodes):
        return []
    said = ("the controller manager runs in the physics node's step (it reads and writes "
            "MjData; docs/how-to/ros2-control.md, How cosim runs it): this is dropped.")
    fix = "delete the remaps and inputs naming /cosim/hardware_* and /cosim/base_command."
    out = [ScenarioNotice(path, f"nodes[{i}] ({spec.name}).remap.{own}", f"{own} -> {graph}: "
                          + said, fix)
           for i, spec in enumerate(model.nodes) for own, graph in spec.remap.items()
           if own in HARDWARE_TOPICS or graph in HARDWARE_TOPICS]
    out += [ScenarioNotice(path, f"nodes[{i}] ({spec.name}).inputs[{j}]", f"input {inp.topic}: "
                           + said, fix)
            for i, spec in enumerate(model.nodes) for j, inp in enumerate(spec.inputs)
            if inp.topic in HARDWARE_TOPICS]
    return out


def fold_managers(path: Path, model: ScenarioModel, params: dict, origins: dict[str, int],
                  one_line: str | None = None
                  ) -> tuple[ScenarioModel, list[ScenarioNotice] | None]:
    """The checked, expanded model with every controller manager node folded into the
    physics node (module docstring); ``params``: each node's checked parameters, by index;
    ``one_line``: the robots: key that made the managers (``with_robot_managers``).
    Notices for physics' inputs that the controllers replace (None: no manager, nothing
    changed). Exit 2 where a manager cannot
    run in physics' step: no physics node, a rate not physics' / n, managers for some
    robots only or declared twice, a controller topic remapped in a swarm."""
    nodes = list(model.nodes)
    classes = {i: class_of(spec) for i, spec in enumerate(nodes)}
    managers = [i for i, cls in classes.items() if getattr(cls, "hardware_role", False)]
    if not managers:
        return model, None
    first = managers[0]
    key = _key(nodes, origins, first)
    worlds = [i for i, cls in classes.items() if getattr(cls, "every_robot", False)]
    if len(worlds) != 1:
        raise ScenarioError(path, key, "a controller manager runs in the physics node's step, "
                            "and the scenario has no physics node." if not worlds else
                            "a controller manager runs in the physics node's step, and the "
                            "scenario has several.", "one node of kind physics.")
    w = worlds[0]
    physics = nodes[w]
    if len({origins.get(nodes[i].name, i) for i in managers}) > 1:
        raise ScenarioError(path, _key(nodes, origins, managers[1]), "a second controller "
                            "manager: one runs for each robot, in the physics step.",
                            "one ros2_control node (for_each: robot in a robots: scenario), "
                            "or robots.controllers.")
    robots = physics.robots or []
    served = sorted(robot_of(nodes[i].name) or "" for i in managers)
    if sorted(robots or [""]) != served:
        raise ScenarioError(path, key, "a controller manager runs in the physics node's step "
                            "for every robot; this one is for " + (", ".join(served) or
                                                                   "the scenario's robot")
                            + " only.", "for_each: robot without robots: (every robot).")
    spec = nodes[first]
    check_manager_rate(path, model, params, origins, one_line)
    cls = classes[first]
    hosted = cls.hosted_params(params[first], spec.name.partition("@")[0])
    joints, base = cls.takes_hardware(params[first])
    replaced = ({JOINT_COMMANDS} if joints else set()) | ({CMD_VEL} if base else set())
    fed = set(_external_topics(nodes))
    inputs, remap, notices = [], {}, []
    for i in managers:
        manager = nodes[i]
        robot = robot_of(manager.name)
        for own_topic, graph in manager.remap.items():
            if graph in HARDWARE_TOPICS or own_topic in HARDWARE_TOPICS:
                continue
            under = graph[:-len(own_topic)] if graph.endswith(own_topic) else None
            if robot is not None and (under is None or under.count("/") > 1):
                raise ScenarioError(path, f"{key}.remap.{own_topic}", "a controller's topic "
                                    "remapped in a swarm: each robot's manager runs in the "
                                    "physics step, its topics under the robot's namespace.",
                                    "no remap (a node of the robot remaps its end instead).")
            if robot is None:
                remap[own_topic] = graph
        for inp in manager.inputs:
            if inp.topic in HARDWARE_TOPICS:
                continue
            graph = manager.remap.get(inp.topic, inp.topic)
            topic = graph if robot is not None else inp.topic
            mode = inp.mode if graph in fed else "delayed"
            inputs.append(InputSpec(topic=topic, mode=mode))
    kept = []
    for j, inp in enumerate(physics.inputs):
        local = _local(inp.topic, robots)
        if inp.topic in HARDWARE_TOPICS or local in replaced:
            if local in replaced:
                notices.append(ScenarioNotice(path, f"{_key(nodes, origins, w)}.inputs[{j}]",
                                              f"{inp.topic}: the robot's controllers command "
                                              "its hardware in the physics step, so physics "
                                              "does not take it; it is dropped.",
                                              "delete the input (a controller's topic, such "
                                              "as the diff drive's ~/cmd_vel, takes it)."))
            continue
        kept.append(inp)
    listed = {inp.topic for inp in kept}
    for inp in inputs:
        if inp.topic not in listed:
            listed.add(inp.topic)
            kept.append(inp)
    physics_remap = {t: g for t, g in physics.remap.items()
                     if t not in HARDWARE_TOPICS and g not in HARDWARE_TOPICS}
    folded = physics.model_copy(update={
        "params": {**physics.params, "controller_manager": hosted.model_dump()},
        "inputs": kept, "remap": {**remap, **physics_remap}})
    nodes[w] = folded
    nodes = [n for i, n in enumerate(nodes) if i not in managers]
    return model.model_copy(update={"nodes": nodes}), notices


def check_manager_rate(path: Path, model: ScenarioModel, params: dict, origins: dict[str, int],
                       one_line: str | None = None) -> None:
    """Exit 2 where the controller manager's update_rate is not the physics node's rate / n
    for a whole n (naming the controllers file, its key and the rates accepted; the robots:
    key that made the managers, ``one_line``, else the node's); nothing without a manager
    or a physics node (said by ``fold_managers``). Checked before the world's timestep fits
    physics' period, so that a ratio such as 1.5 names the file."""
    nodes = model.nodes
    classes = {i: class_of(spec) for i, spec in enumerate(nodes)}
    managers = [i for i, cls in classes.items() if getattr(cls, "hardware_role", False)]
    worlds = [i for i, cls in classes.items() if getattr(cls, "every_robot", False)]
    if not managers or len(worlds) != 1:
        return
    first, w = managers[0], worlds[0]
    spec, physics = nodes[first], nodes[w]
    ratio = Fraction(spec.period_ns) / Fraction(physics.period_ns)
    if ratio.denominator != 1 or ratio < 1:  # update_rate = physics' rate / n
        if one_line is None and model.robots is not None and model.robots.controllers:
            one_line = ROBOTS_CONTROLLERS
        key = _key(nodes, origins, first)
        raise _rate_error(path, one_line or f"{key}.rate",
                          _key(nodes, origins, w), spec.period_ns, physics.period_ns,
                          getattr(params.get(first), "controllers", None))


def _local(topic: str, robots: list[str]) -> str:
    """``topic`` without the namespace of the robot it is under ('/robot_2/cmd_vel' ->
    '/cmd_vel'), as it is where it is under none."""
    head, _, rest = topic[1:].partition("/")
    return f"/{rest}" if rest and head in robots else topic


def _external_topics(nodes: list[NodeSpec]) -> dict[str, str]:
    """The graph topics the external node feeds (clients of an interactive run)."""
    for spec in nodes:
        if spec.name == EXTERNAL_NAME:
            return dict(spec.params.get("topics", {}))
    return {}


def _rate_error(path: Path, key: str, physics_key: str, period_ns, physics_ns,
                controllers: str | list[str] | None) -> ScenarioError:
    """The manager's update_rate is not physics' rate / n for a whole n: which file and key,
    and the rates accepted."""
    if isinstance(controllers, list):
        controllers = " + ".join(controllers)
    hz = lambda ns: f"{float(NS_PER_S / ns):g}"  # noqa: E731 - one short format
    rate, physics_rate = hz(period_ns), hz(physics_ns)
    where = (f"{controllers}: controller_manager.ros__parameters.update_rate"
             if controllers else "update_rate in the controllers file")
    return ScenarioError(
        path, key, f"the controller manager runs in the physics node's step, at every n-th "
        f"physics activation for a whole n, so its update_rate ({rate} Hz, {where}) must be "
        f"physics' rate ({physics_rate} Hz, {physics_key}.rate) divided by a whole number.",
        f"update_rate: one of {whole_divisions(NS_PER_S / physics_ns)} in "
        f"{controllers or 'the controllers file'}, or physics' rate: a whole multiple of "
        f"{rate} (where the world's timestep divides its period).")


def _key(nodes: list[NodeSpec], origins: dict[str, int], i: int) -> str:
    """A node's key as the file gives it (a template instance: its template's)."""
    name = nodes[i].name
    return f"nodes[{origins.get(name, i)}] ({name.partition('@')[0]})"


MANAGER_NAME = "controller_manager"
ROBOTS_CONTROLLERS = "robots.controllers"
ROBOTS_DESCRIPTION = "robots.description"


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


def with_robot_managers(path: Path, model: ScenarioModel, description: str = "",
                        tagged: tuple[str, ...] = ()
                        ) -> tuple[ScenarioModel, str | None, list[ScenarioNotice]]:
    """The model with ``robots.controllers`` made a node: ``controller_manager``,
    ``for_each: robot``, at the file's update_rate, taking same tick each of its
    controllers' topics that a robot's node or physics publishes (by the node's own names,
    as templates' topics are the robot's); the robots: key that named the file (None: no
    manager added); notices. Without ``robots.controllers``, the files ``tagged`` by the
    ``<parameters>`` of the robot ``description``'s ros2_control plugin tag (as
    gz_ros2_control reads them; several merged in order) make it, unless a node of the
    scenario runs a manager already; with both, ``robots.controllers`` wins and a notice
    says so where they differ; ``robots.controllers: false`` adds none. Exit 2 naming the
    key where the file is missing or wrong or a node of the scenario already has the
    name."""
    robots = model.robots
    if robots is None or robots.controllers is False:  # false: no manager, tag or not
        return model, None, []
    notices = []
    if robots.controllers is not None:
        key, files = ROBOTS_CONTROLLERS, robots.controllers
        if tagged and [str((path.parent / files).resolve())] != list(tagged):
            notices.append(ScenarioNotice(
                path, key, f"the robot description's ros2_control plugin tag names "
                f"{' + '.join(tagged)} (<parameters>); {files} is used instead.",
                "one of the two, or both naming the same file."))
    elif tagged and not any(getattr(class_of(spec), "hardware_role", False)
                            for spec in model.nodes):
        key = ROBOTS_DESCRIPTION
        files = tagged[0] if len(tagged) == 1 else list(tagged)
        for file in tagged:
            if not Path(file).is_file():
                raise ScenarioError(
                    path, key, f"robot description {description}: its ros2_control plugin "
                    f"tag's <parameters> names a controllers file that does not exist (tried "
                    f"{file}).", "<parameters>$(find PKG)/config/FILE.yaml</parameters> (or "
                    "package://PKG/...) with PKG in robots.urdf.packages, "
                    "robots.controllers naming the controllers file, or robots.controllers: "
                    "false for none.")
    else:
        return model, None, notices
    if any(spec.name == MANAGER_NAME for spec in model.nodes):
        raise ScenarioError(path, key, f"the scenario also has a node named {MANAGER_NAME}.",
                            "robots.controllers, or that node (not both)."
                            if key == ROBOTS_CONTROLLERS else "rename that node.")
    kind = hardware_kind()
    cls = class_of(NodeSpec(name=MANAGER_NAME, kind=kind, rate=1)) if kind else None
    if cls is None:
        raise ScenarioError(path, key, "no node kind runs a controller manager here.",
                            "leave robots.controllers out.")
    try:
        params = cls.Params.model_validate({"controllers": files},
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
                       params={"controllers": files}, inputs=inputs)
    return model.model_copy(update={"nodes": [*model.nodes, manager]}), key, notices


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
