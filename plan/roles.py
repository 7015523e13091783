"""What part a node plays in a run: one role per node, decided once when the scenario loads.

Every layer that treats nodes differently asks the node's role (``NodePlan.role``), never
its keys again: which starter starts it (``orchestrator.starters.STARTERS``), whether it
shares a process (``plan.packing``), whether a gate acknowledges its ticks, whether the
orchestrator stands in for it. A new kind of participant is a new role here and one
starter there.
"""

from __future__ import annotations

from enum import Enum

from plan.gates import PYTHON_GATE, RMW_GATE, gate_for
from plan.model import NodeSpec


class NodeRole(Enum):
    """The part a node plays in a run."""

    STEP = "step"  # a step node in a cosim node process the orchestrator starts
    USER_STARTED = "user_started"  # a step node you start yourself (``external: true``)
    ORCHESTRATOR = "orchestrator"  # the external node: stepped by the orchestrator itself
    PYTHON_GATE = "python_gate"  # a foreign program behind the Python gate
    RMW_GATE = "rmw_gate"  # a foreign program behind the RMW gate
    UNGATED = "ungated"  # a foreign program no gate serves (counted message by message)

    @property
    def is_foreign(self) -> bool:
        """A foreign ROS 2 program started from a command (gated or not)."""
        return self in _FOREIGN

    @property
    def is_gated(self) -> bool:
        """A foreign program a gate serves: it acknowledges every tick with how many
        messages it published on each output, so it may publish any number per tick (the
        delivery contract, docs/how-to/foreign-programs.md)."""
        return self in _GATE

    @property
    def gate(self) -> str | None:
        """The gate that serves it ('python' or 'rmw', ``plan.gates``), or None."""
        return _GATE.get(self)

    @property
    def runs_step_runtime(self) -> bool:
        """A cosim step node in a node process (the orchestrator's or yours): it reports on
        /cosim/status, follows /clock and /cosim/command and takes live parameters."""
        return self in (NodeRole.STEP, NodeRole.USER_STARTED)

    @property
    def stood_in(self) -> bool:
        """The orchestrator holds its participant (a foreign program's proxy, the external
        node's source): that reports for it and records its part."""
        return self is NodeRole.ORCHESTRATOR or self.is_foreign

    @property
    def packable(self) -> bool:
        """It may share a process with other nodes (``process:``, ``--pack``)."""
        return self is NodeRole.STEP


_GATE = {NodeRole.PYTHON_GATE: PYTHON_GATE, NodeRole.RMW_GATE: RMW_GATE}
_FOREIGN = frozenset({NodeRole.PYTHON_GATE, NodeRole.RMW_GATE, NodeRole.UNGATED})
_OF_GATE = {PYTHON_GATE: NodeRole.PYTHON_GATE, RMW_GATE: NodeRole.RMW_GATE,
            None: NodeRole.UNGATED}


def role_of(spec: NodeSpec, class_ref: str, gate: str, external_ref: str) -> NodeRole:
    """The role of a node with this spec and class, ``gate`` its ``params.gate`` (foreign
    programs) and ``external_ref`` the class the scenario's ``external:`` section becomes."""
    if class_ref == external_ref:
        return NodeRole.ORCHESTRATOR
    if spec.command is not None:
        return _OF_GATE[gate_for(spec.command, gate)]
    return NodeRole.USER_STARTED if spec.external else NodeRole.STEP
