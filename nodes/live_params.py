"""Parameters that change while a run goes: a node's ``Params`` as ROS 2 parameters, and the
input that carries the changes (``/cosim/params/<node>``, plan/interactive.py).

A node's parameters are its checked ``Params`` flattened to dotted ROS 2 names
(``lidar.beams``; a value left out, ``None``, is not a parameter). A change message is an
rcl_interfaces/msg/ParameterEvent naming the node whose ``changed_parameters`` hold every
parameter changed since the run started, with its current value: the message is cumulative,
so taking it again (the external node publishes it at every activation) changes nothing.
Every driver (node process, in-process reference) applies it through ``ParamsInput``
before the step, so the outputs cannot depend on the driver.
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel
from rcl_interfaces.msg import ParameterEvent

from nodes.contract import StepNode
from plan.interactive import params_topic

SCALARS = (bool, int, float, str)


def flatten(params: BaseModel) -> dict[str, Any]:
    """Dotted name -> value of every parameter a ROS 2 parameter can hold (scalars and
    non-empty lists of one scalar type; nested mappings give dotted names)."""
    out: dict[str, Any] = {}

    def walk(prefix: str, value: Any) -> None:
        if isinstance(value, dict):
            for key, item in value.items():
                walk(f"{prefix}{key}.", item)
        elif isinstance(value, SCALARS):
            out[prefix[:-1]] = value
        elif isinstance(value, list | tuple) and value and len({type(v) for v in value}) == 1 \
                and isinstance(value[0], SCALARS):
            out[prefix[:-1]] = list(value)

    walk("", params.model_dump())
    return out


def with_changes(params: BaseModel, changes: dict[str, Any]) -> BaseModel:
    """``params`` with dotted ``changes`` applied, checked by its model (ValidationError)."""
    data = params.model_dump()
    for name, value in changes.items():
        *path, last = name.split(".")
        target = data
        for part in path:
            target = target.setdefault(part, {})
        target[last] = value
    return type(params).model_validate(data)


def change_message(node: str, changes: dict[str, Any]) -> ParameterEvent:
    """The ParameterEvent that carries ``changes`` (every change so far) into ``node``."""
    from rclpy.parameter import Parameter

    msg = ParameterEvent(node=node)
    msg.changed_parameters = [Parameter(name, value=value).to_parameter_msg()
                              for name, value in sorted(changes.items())]
    return msg


def changes_in(msg: ParameterEvent) -> dict[str, Any]:
    """The dotted name -> value changes a ParameterEvent carries."""
    from rclpy.parameter import parameter_value_to_python

    out = {}
    for param in msg.changed_parameters:
        value = parameter_value_to_python(param.value)
        out[param.name] = list(value) if isinstance(value, list | tuple) else value
    return out


class ParamsInput:
    """Applies the parameter changes a node receives, before its step."""

    def __init__(self, node: str, scenario_params: BaseModel):
        self.topic = params_topic(node)
        self.scenario_params = scenario_params
        self.last: ParameterEvent | None = None

    @classmethod
    def of(cls, plan) -> ParamsInput | None:
        """The ParamsInput of a node plan that takes parameter changes, else None."""
        topic = params_topic(plan.name)
        if any(inp.topic == topic for inp in plan.inputs):
            return cls(plan.name, plan.params)
        return None

    def apply(self, node: StepNode, inputs: dict[str, Any]) -> dict[str, Any]:
        """The step's inputs without the change message, after handing a new change to the
        node (``set_params``); nothing has arrived while the message names no node."""
        inputs = dict(inputs)
        msg = inputs.pop(self.topic, None)
        if msg is not None and msg.node and msg != self.last:
            node.set_params(with_changes(self.scenario_params, changes_in(msg)))
            self.last = msg
        return inputs

    def forget(self) -> None:
        """The node was reset: its parameters are the scenario's again."""
        self.last = None
