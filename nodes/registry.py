"""The built-in node kinds by name, and loading of node classes given as 'package.module:Class'.

The kinds live here, beside their code. The plan, which sits below this package, sees them
only through the catalogue that importing this package provides to it (``plan.kinds``), so
the dependency runs one way: nodes -> plan.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass, field

from nodes.contract import StepNode
from plan.kinds import provide

KINDS: dict[str, str] = {
    "physics": "nodes.physics.node:PhysicsNode",
    "sensors": "nodes.sensors.node:SensorsNode",
    "control": "nodes.control.node:ControlNode",
    "joint_targets": "nodes.arm.node:JointTargetsNode",
    "ros2_control": "nodes.ros2_control.node:ControllerManagerNode",
    "counter": "nodes.testing:CounterNode",
    "integrator": "nodes.testing:IntegratorNode",
    "wallclock": "nodes.testing:WallClockNode",
    "faulty": "nodes.testing:FaultyNode",
}
TEST_KINDS = frozenset({"counter", "integrator", "wallclock", "faulty"})  # the suite's own
FOREIGN = "nodes.foreign_program:ForeignNode"
EXTERNAL = "nodes.external_inputs:ExternalInputs"


def is_step_node(cls: object) -> bool:
    """Whether ``cls`` is a class deriving from nodes.contract.StepNode."""
    return isinstance(cls, type) and issubclass(cls, StepNode)


def load_class(ref: str) -> type:
    """Import 'package.module:Class' and check that it is a StepNode subclass."""
    module_name, _, class_name = ref.partition(":")
    if not module_name or not class_name:
        raise ValueError(f"{ref!r} is not of the form 'package.module:Class'")
    module = importlib.import_module(module_name)
    cls = getattr(module, class_name, None)
    if cls is None:
        raise ValueError(f"module {module_name!r} has no class {class_name!r}")
    if not is_step_node(cls):
        raise ValueError(f"{ref} is not a subclass of nodes.contract.StepNode")
    return cls


def kind_class(kind: str) -> type:
    """The step class of a built-in node kind."""
    return load_class(KINDS[kind])


@dataclass(frozen=True)
class Catalogue:
    """What the plan needs of the node kinds (``plan.kinds.Catalogue``)."""

    kinds: dict[str, str] = field(default_factory=lambda: KINDS)
    listed: tuple[str, ...] = tuple(sorted(set(KINDS) - TEST_KINDS))
    foreign: str = FOREIGN
    external: str = EXTERNAL

    def load(self, ref: str) -> type:
        """The StepNode class named by 'package.module:Class'."""
        return load_class(ref)


provide(Catalogue())
