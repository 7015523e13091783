"""Every cosim node's parameters as ROS 2 parameters, served by the orchestrator.

For each cosim node of a run, an rclpy node of the same name offers the standard
rcl_interfaces services (``/<node>/get_parameters``, ``set_parameters``,
``list_parameters``, ``describe_parameters``, ...), so ``ros2 param`` and any parameter
client work. The parameters are the node's checked ``Params``, flattened to dotted names.
Those the node reads at every step (its class's ``runtime_params``) can be set in an
interactive run: a set is checked like the scenario (a bad value is refused with the
reason), then enters the run as the node's /cosim/params/<node> message at the external
node's next activation and is recorded (nodes/live_params.py). The others are read-only.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

from pydantic import BaseModel, ValidationError
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult

from nodes.live_params import change_message, flatten, with_changes
from orchestrator.ros_surface.simcontrol import RunControl
from plan.interactive import params_topic
from plan.robots import namespace_in, robot_of, ros_identity
from plan.scenario import EXTERNAL_NAME, NodePlan
from plan.validation import describe_validation_error, field_of, inner_model
from runtime.arrivals import Arrivals

if TYPE_CHECKING:
    from plan.scenario import Scenario


class NodeParameters:
    """One cosim node's parameters on an rclpy node named like it."""

    def __init__(self, context, plan: NodePlan, cls: type, arrivals: Arrivals | None,
                 control: RunControl, external_period: int, namespace: str | None = None):
        """``namespace``: the ROS namespace of the node's robot where it is not the robot's
        name ('' at the root; ``plan.robots.ros_identity``)."""
        import rclpy

        self.plan = plan
        self.control = control
        self.external_period = external_period
        self.topic = params_topic(plan.name)
        takes = any(inp.topic == self.topic for inp in plan.inputs)
        self.arrivals = arrivals if takes and arrivals is not None else None
        self.why_fixed = ("the scenario is not interactive (set interactive: true)" if not takes
                          else "this run replays recorded inputs" if arrivals is None else "")
        self.scenario_values = flatten(plan.params)
        self.changes: dict[str, Any] = {}
        self._lock = threading.Lock()
        self._resetting = False
        name, namespace = ros_identity(plan.name, namespace)
        self.node = rclpy.create_node(name, namespace=namespace, context=context,
                                      enable_rosout=False)
        for name, value in self.scenario_values.items():
            runtime = name.split(".")[0] in cls.runtime_params
            self.node.declare_parameter(name, value, describe(type(plan.params), name, runtime))
        self.node.add_on_set_parameters_callback(self._on_set)

    def _on_set(self, params) -> SetParametersResult:
        if self._resetting:
            return SetParametersResult(successful=True)
        unknown = [p.name for p in params if p.name not in self.scenario_values]
        if unknown:
            return _refuse(f"{', '.join(unknown)}: not a parameter of cosim node "
                           f"{self.plan.name!r}; see list_parameters")
        if self.arrivals is None:
            return _refuse(f"{self.plan.name}'s parameters cannot change in this run: "
                           f"{self.why_fixed}")
        with self._lock:
            changes = {**self.changes, **{p.name: _plain(p.value) for p in params}}
            problem = self.check(changes)
            if problem:
                return _refuse(problem)
            self.changes = changes
            self.arrivals.put(self.topic, change_message(self.plan.name, changes))
        k = -(-self.control.boundary // self.external_period) * self.external_period
        return SetParametersResult(successful=True, reason=(
            f"enters the run at tick {k} (the next tick boundary) or, if the run is past it, "
            f"the next one; node {self.plan.name} uses it from its first step after that"))

    def check(self, changes: dict[str, Any]) -> str | None:
        """Why the node's parameters with ``changes`` are refused, as the scenario's
        checks would say it, or None."""
        for name, value in changes.items():
            values = value if isinstance(value, list) else [value]
            if any(isinstance(v, float) and not math.isfinite(v) for v in values):
                return f"{self.plan.name}.{name}: {value!r} is not a finite number"
        try:
            with_changes(self.plan.params, changes)
        except ValidationError as exc:
            data = self.plan.params.model_dump()
            key, problem, accepted = describe_validation_error(exc, data, type(self.plan.params))
            return f"{self.plan.name}.{key}: {problem} Accepted: {accepted}"
        return None

    def reset(self) -> None:
        """The run was reset: back to the scenario's values."""
        import rclpy.parameter

        with self._lock:
            names, self.changes = list(self.changes), {}
            self._resetting = True
            try:
                self.node.set_parameters([rclpy.parameter.Parameter(
                    n, value=self.scenario_values[n]) for n in names])
            finally:
                self._resetting = False

    def destroy(self) -> None:
        """Remove the node and its services."""
        self.node.destroy_node()


def parameter_nodes(context, scenario: Scenario, arrivals: Arrivals | None, control: RunControl
                    ) -> Iterator[NodeParameters]:
    """A NodeParameters for every cosim node of the run (not foreign programs, not the
    external node), each as it is made (so that the caller holds those made before one
    fails, to remove them)."""
    from nodes.registry import load_class

    period = scenario.schedule.periods.get(EXTERNAL_NAME, 1)
    for plan in served(scenario):
        namespace = namespace_in(scenario.robots, robot_of(plan.name))
        yield NodeParameters(context, plan, load_class(plan.class_ref), arrivals, control,
                             period, namespace)


PARAMETER_NODES_MAX = 64
"""Above this many cosim nodes, a robot's node serves its parameters only where it is the
first robot's, or it takes parameter changes (an interactive run). Each served node is an
rclpy node of eight services: at 256 robots (513 nodes) they took about 600 MB and 30 CPU
seconds of the orchestrator, more than the whole run's nodes, and every process discovered
their endpoints."""


def served(scenario: Scenario) -> list[NodePlan]:
    """The cosim nodes whose parameters the run serves: every one, but in a run of more than
    ``PARAMETER_NODES_MAX`` the copies of a ``for_each: robot`` node only for the first
    robot (their values are the template's, as the scenario file gives them),
    besides those that take parameter changes."""
    plans = [p for p in scenario.nodes.values() if p.role.runs_step_runtime]
    if len(plans) <= PARAMETER_NODES_MAX:
        return plans
    first: dict[str, str] = {}
    out = []
    for plan in plans:
        robot = robot_of(plan.name)
        takes = any(inp.topic == params_topic(plan.name) for inp in plan.inputs)
        if robot is None or takes or first.setdefault(plan.name.partition("@")[0],
                                                      robot) == robot:
            out.append(plan)
    return out


def describe(model: type[BaseModel], name: str, runtime: bool) -> ParameterDescriptor:
    """The parameter's description from its field: text, bounds, and whether it can change."""
    info = _field(model, name)
    text = (info.description or "") if info is not None else ""
    when = ("changes take effect at the next tick boundary (interactive runs)" if runtime
            else "fixed once the node is set up")
    bounds = [f"{symbol} {getattr(m, attr)}" for m in (info.metadata if info else [])
              for attr, symbol in (("gt", ">"), ("ge", ">="), ("lt", "<"), ("le", "<="))
              if hasattr(m, attr)]
    return ParameterDescriptor(name=name, description=f"{text}; {when}" if text else when,
                               read_only=not runtime, additional_constraints=", ".join(bounds))


def _field(model: type[BaseModel], name: str):
    """The FieldInfo of a dotted parameter name, following nested models."""
    current: Any = model
    info = None
    for part in name.split("."):
        current = inner_model(current)
        if current is None:
            return None
        info = field_of(current, part)
        if info is None:
            return None
        current = info.annotation
    return info


def _plain(value: Any) -> Any:
    """A parameter value as plain Python (arrays as lists)."""
    return value if isinstance(value, bool | int | float | str) else list(value)


def _refuse(reason: str) -> SetParametersResult:
    return SetParametersResult(successful=False, reason=reason)
