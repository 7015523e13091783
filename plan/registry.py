"""Node kinds by name, and loading of user classes given as 'package.module:Class'.

Classes are named by text and imported on demand, so the plan never imports the nodes
package (it sits below it); a loaded class must derive from ``nodes.contract.StepNode``.
"""

from __future__ import annotations

import importlib

STEP_NODE = ("nodes.contract", "StepNode")

KINDS: dict[str, str] = {
    "physics": "nodes.physics.node:PhysicsNode",
    "sensors": "nodes.sensors.node:SensorsNode",
    "control": "nodes.control.node:ControlNode",
    "joint_targets": "nodes.arm.node:JointTargetsNode",
    "counter": "nodes.testing:CounterNode",
    "integrator": "nodes.testing:IntegratorNode",
    "wallclock": "nodes.testing:WallClockNode",
    "faulty": "nodes.testing:FaultyNode",
}


def is_step_node(cls: object) -> bool:
    """Whether ``cls`` is a class deriving from nodes.contract.StepNode."""
    return isinstance(cls, type) and any((base.__module__, base.__name__) == STEP_NODE
                                         for base in cls.__mro__)


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
