"""The controller manager's logic, with no transport: it loads the controllers of a file
(a type cosim does not serve loads as a name and a type, and cannot be activated),
configures them, switches them (deactivations first, then activations, as one request) and
updates the active ones in file order, routing their subscriptions' messages to them and
their topics (``~/x`` under the controller's name) out of them.

The manager keeps what each subscribed topic held at the last tick, whatever the state of
its controller, and gives a controller only a message that differs from it (an arrival):
a node's new publication carries its tick's stamp; the external node republishes the latest
message from outside at every tick (each with that tick's stamp), so on its topics
(``held``) the stamp is left out of the comparison. So a message sent before or while a
controller is inactive is dropped, as upstream's inactive controller drops its
subscriptions' messages, and is not taken again at its activation."""

from __future__ import annotations

from collections.abc import Collection, Iterable, Mapping
from functools import cache
from typing import Any

from nodes.ros2_control.config import ControllersFile
from nodes.ros2_control.hardware import joint_mode_conflict
from nodes.ros2_control.interface import (
    ControllerInterface,
    HardwareState,
    LifecycleState,
    Update,
)
from nodes.ros2_control.registry import controller_class


@cache  # the same few names at every update
def resolve(controller: str, topic: str) -> str:
    """A controller's topic as the graph names it: ``~/x`` -> ``/<controller>/x``."""
    return f"/{controller}/{topic[2:]}" if topic.startswith("~/") else topic


def load(file: ControllersFile, namespace: str = "") -> dict[str, ControllerInterface | None]:
    """Every controller of the file, configured (None: a type cosim does not serve), its
    node in ROS namespace ``namespace`` ('' the root)."""
    out: dict[str, ControllerInterface | None] = {}
    for entry in file.controllers:
        ctrl = load_one(file, entry.name, namespace)
        if ctrl is not None:
            ctrl.configure()
        out[entry.name] = ctrl
    return out


def load_one(file: ControllersFile, name: str, namespace: str = "") -> ControllerInterface | None:
    """Controller ``name`` of the file, unconfigured (None: a type cosim does not serve),
    its node in ROS namespace ``namespace``."""
    entry = file.named(name)
    cls = controller_class(entry.type)
    if cls is None or entry.params is None:
        return None
    ctrl = cls(entry.name, entry.params)
    ctrl.namespace = namespace
    return ctrl


STATE_CODES = {"unloaded": 0.0, "unconfigured": 1.0, "inactive": 2.0, "active": 3.0}
"""A controller's state as the ``state:<name>`` metric carries it."""


def state_of(ctrl: ControllerInterface | None) -> str:
    """A loaded controller's lifecycle state as list_controllers says it (a type cosim does
    not serve is loaded and never configured)."""
    return "unconfigured" if ctrl is None else ctrl.lifecycle.value


def lifecycle_problem(file: ControllersFile, controllers: Mapping[str, object],
                      states: Mapping[str, str], verb: str, name: str) -> str | None:
    """Why ``verb`` (load, unload, configure) of controller ``name`` cannot be done, given
    the loaded controllers' ``states``, or None (upstream's refusals)."""
    if verb == "load":
        if name in states:
            return f"A controller named '{name}' was already loaded inside the controller manager"
        if name not in controllers:
            return (f"The 'type' param was not defined for '{name}' in the controllers file "
                    f"{file.file.name}: controllers: " + ", ".join(controllers))
        return None
    if name not in states:
        return (f"Could not {verb} controller with name '{name}' because no controller with "
                "this name exists")
    if verb == "unload" and states[name] == "active":
        return f"Could not unload controller with name '{name}' because it is still active"
    if verb == "configure":
        if states[name] == "active":
            return f"Controller '{name}' can not be configured from 'active' state."
        if controllers.get(name) is None:
            return (f"controller '{name}' has type {file.named(name).type!r}, which cosim "
                    "cannot run (it is loaded and stays unconfigured)")
    return None


def claim_conflict(controllers: Mapping[str, ControllerInterface | None],
                   active: Iterable[str]) -> str | None:
    """The first command interface two of the ``active`` controllers claim, or the first
    joint they command through two interfaces (its position and velocity: its actuator
    takes one at a time, as upstream's hardware rejects it), said, or None."""
    owner: dict[str, str] = {}
    claims = []
    for name in active:
        ctrl = controllers.get(name)
        command = ctrl.claim().command if ctrl is not None else ()
        claims.append((name, command))
        for interface in command:
            if interface in owner:
                return (f"{interface} is claimed by {owner[interface]!r} and {name!r}, both "
                        "active")
            owner[interface] = name
    both = joint_mode_conflict(claims)
    if both is not None:
        joint, first, by, second, by_second = both
        return (f"joint {joint!r} would be commanded through {first} by {by!r} and {second} "
                f"by {by_second!r}, both active: its hardware takes one command interface "
                "per joint at a time")
    return None


def switch_problem(file: ControllersFile, controllers: Mapping[str, ControllerInterface | None],
                   active: Iterable[str], activate: list[str], deactivate: list[str],
                   unservable: Mapping[str, str] | None = None) -> str | None:
    """Why a switch cannot be done (an unknown controller, a type cosim cannot run, one whose
    interfaces the hardware lacks (``unservable``: name -> why), two active controllers
    claiming one command interface), or None."""
    unknown = [n for n in [*activate, *deactivate] if n not in controllers]
    if unknown:
        return f"no controller {unknown[0]!r}; controllers: " + ", ".join(controllers)
    for name in activate:
        if controllers[name] is None:
            return (f"controller {name!r} has type {file.named(name).type!r}, which cosim "
                    "cannot run (it is loaded and stays inactive)")
        if name in (unservable or {}):
            return f"controller {name!r} cannot be activated: {unservable[name]}"
    after = [n for n in controllers if (n in active and n not in deactivate) or n in activate]
    return claim_conflict(controllers, after)


class Route:
    """What an update gives a loaded controller and takes from it, named once: its
    subscriptions (own name, graph name) and its publications (own name -> graph name)."""

    __slots__ = ("name", "controller", "subscriptions", "publications", "absolute")

    def __init__(self, name: str, controller: ControllerInterface,
                 subscriptions: tuple[tuple[str, str], ...], publications: dict[str, str]):
        self.name, self.controller = name, controller
        self.subscriptions, self.publications = subscriptions, publications
        # every topic it publishes is named as the graph names it (no ~/x)
        self.absolute = all(own == graph for own, graph in publications.items())

    @classmethod
    def of(cls, name: str, ctrl: ControllerInterface) -> Route:
        """The route of controller ``name``."""
        return cls(name, ctrl, tuple((t, resolve(name, t)) for t in ctrl.subscriptions()),
                   {t: resolve(name, t) for t in ctrl.publications()})


class ControllerManager:
    """The controllers of one file, their lifecycle, switches and updates."""

    def __init__(self, file: ControllersFile, namespace: str = ""):
        """``namespace``: the robot's, its controllers' nodes' ('' the root)."""
        self.file = file
        self.namespace = namespace
        self.controllers = load(file, namespace)
        self.unloaded: set[str] = set()
        self.held: dict[str, Any] = {}  # topic -> its message at the last tick
        self.unservable: dict[str, str] = {}  # controller -> what the hardware lacks for it
        self._routes: list[Route] | None = None  # made at the first update after a load
        # prefix -> controller -> its metrics' keys (active, state, own metric -> key)
        self._metric_keys: dict[str, dict[str, tuple[str, str, dict[str, str]]]] = {}

    def states(self) -> dict[str, str]:
        """Every loaded controller's state, in file order."""
        return {n: state_of(c) for n, c in self.controllers.items() if n not in self.unloaded}

    def lifecycle(self, verb: str, name: str) -> str | None:
        """load_controller (unconfigured), unload_controller (an inactive or unconfigured
        one goes), configure_controller (-> inactive; an inactive one is configured again);
        why not (and nothing done), or None."""
        problem = lifecycle_problem(self.file, self.controllers, self.states(), verb, name)
        if problem:
            return problem
        if verb == "load":
            self.controllers[name] = load_one(self.file, name, self.namespace)
            self._routes = None
            self.unloaded.discard(name)
        elif verb == "unload":
            ctrl = self.controllers[name]
            if ctrl is not None:
                ctrl.finalize()
            self.unloaded.add(name)
        else:
            ctrl = self.controllers[name]
            if ctrl.lifecycle is LifecycleState.INACTIVE:  # cleaned up, then configured
                ctrl.lifecycle = LifecycleState.UNCONFIGURED
            ctrl.configure()
        return None

    def active(self) -> list[str]:
        """The active controllers, in file order."""
        return [n for n, c in self.controllers.items() if c is not None and c.active]

    def claimed(self) -> list[str]:
        """The command interfaces the active controllers claim, in file order."""
        return [i for n, c in self.controllers.items() if c is not None and c.active
                for i in c.claim().command]

    def notes(self) -> list[str]:
        """What the controllers read and do not act on, and the types cosim cannot run."""
        out = [n for c in self.controllers.values() if c is not None for n in c.notes()]
        out += [f"{e.name}: type {e.type} is loaded, and cosim cannot run it: it cannot be "
                "activated." for e in self.file.unserved]
        return out

    def activate(self, names: list[str], state: HardwareState) -> Update:
        """Activate ``names`` (already checked) with the hardware's state loaned."""
        out = Update()
        for name in names:
            ctrl = self.controllers[name]
            if ctrl is not None and not ctrl.active:
                out.commands.update(ctrl.activate(state).commands)
        return out

    def switch(self, activate: list[str], deactivate: list[str], state: HardwareState
               ) -> tuple[Update, str | None]:
        """Deactivate, then activate; the commands they leave, and why nothing was switched
        (or None)."""
        problem = switch_problem(self.file, self.controllers, self.active(), activate,
                                 deactivate, self.unservable)
        states = self.states()
        if problem is None:
            problem = next((f"controller {n!r} is {states.get(n, 'not loaded')}" for n in
                            activate if states.get(n) not in ("inactive", "active")), None)
        if problem:
            return Update(), problem
        out = Update()
        for name in deactivate:
            ctrl = self.controllers[name]
            if ctrl is not None and ctrl.active:
                out.commands.update(ctrl.deactivate().commands)
        out.commands.update(self.activate(activate, state).commands)
        return out, None

    def update(self, time_ns: int, period_ns: int, inputs: Mapping[str, Any],
               held: Collection[str] = ()) -> Update:
        """Give each active controller its arrivals, then update it; their commands (a later
        controller's over an earlier one's) and what they publish, under the graph's names.
        ``held``: the topics the external node feeds (see the module)."""
        out = Update()
        commands, published, notes = out.commands, out.published, out.notes
        owned = True  # ``commands`` is this update's own (not a controller's, passed on)
        routes = self._routes
        if routes is None:
            routes = self._routes = [Route.of(name, ctrl) for name, ctrl in
                                     self.controllers.items() if ctrl is not None]
        for route in routes:
            ctrl = route.controller
            arrived = [(topic, msg) for topic, graph in route.subscriptions
                       if graph in inputs
                       and (msg := self._arrival(graph, inputs, held)) is not None
                       ] if route.subscriptions else ()
            if ctrl.lifecycle is not LifecycleState.ACTIVE:
                continue
            for topic, msg in arrived:
                notes += ctrl.on_message(topic, msg, time_ns)
            done = ctrl.update(time_ns, period_ns)
            if done.commands:  # one controller's commands passed on as they are
                if not commands:
                    commands = out.commands = done.commands
                else:
                    if not owned:
                        commands = out.commands = dict(commands)
                    commands.update(done.commands)
                owned = commands is not done.commands
            if route.absolute:
                published.update(done.published)
            else:
                names = route.publications
                for topic, msg in done.published.items():
                    published[names.get(topic) or resolve(route.name, topic)] = msg
            if done.notes:
                notes += done.notes
        return out

    def _arrival(self, topic: str, inputs: Mapping[str, Any], held: Collection[str]) -> Any:
        """The message on ``topic`` if it differs from the one of the last tick."""
        msg = inputs.get(topic)
        if msg is None:
            return None
        last = self.held.get(topic)
        if last is msg:  # the sample taken again (a slower producer's): no arrival
            return None
        self.held[topic] = msg
        if last is None:
            return msg
        same = same_message(last, msg) if topic in held else last == msg
        return None if same else msg

    def metrics(self, prefix: str = "") -> dict[str, float]:
        """``active:<name>`` (1 or 0) of every controller, its ``state:<name>`` (0 unloaded,
        1 unconfigured, 2 inactive, 3 active), then each one's own (``<metric>:<name>``);
        every key after ``prefix``. (Asked at every tick of a multi-process run: the keys
        are made once.)"""
        keys = self._metric_keys.get(prefix)
        if keys is None:
            keys = self._metric_keys[prefix] = {}
        out: dict[str, float] = {}
        unloaded = self.unloaded
        for name, ctrl in self.controllers.items():
            named = keys.get(name)
            if named is None:
                named = keys[name] = (f"{prefix}active:{name}", f"{prefix}state:{name}", {})
            active, state, own = named
            out[active] = float(ctrl is not None and ctrl.active)
            out[state] = STATE_CODES["unloaded" if name in unloaded else state_of(ctrl)]
        for name, ctrl in self.controllers.items():
            if ctrl is not None:
                own = keys[name][2]
                for metric, value in ctrl.metrics().items():
                    key = own.get(metric)
                    if key is None:
                        key = own[metric] = f"{prefix}{metric}:{name}"
                    out[key] = value
        return out


def same_message(a: Any, b: Any) -> bool:
    """Whether two messages are equal but for their header's stamp (the tick's, given to
    every publication)."""
    if type(a) is not type(b):
        return False
    if not hasattr(a, "get_fields_and_field_types"):
        return a == b
    for field in a.get_fields_and_field_types():
        x, y = getattr(a, field), getattr(b, field)
        if field == "header" and hasattr(x, "stamp"):
            equal = x.frame_id == y.frame_id
        else:
            equal = x == y
            if not isinstance(equal, bool):  # a fixed-size array: numpy, elementwise
                equal = bool(equal.all())
        if not equal:
            return False
    return True
