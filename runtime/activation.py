"""One activation of a node, written once for every driver (the lockstep runtime, the
in-process reference, the realtime runtime, the external node in the orchestrator): apply
parameter changes, step, take the notes (also when the step fails), then check, stamp and
serialise the outputs. The bytes, and hence the digest, cannot differ between drivers."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from nodes.contract import StepNode, Tick, take_output_marks
from nodes.live_params import ParamsInput
from runtime.cdr.encode import ConstantTails
from runtime.exchange import prepare_outputs
from runtime.notes import Note

if TYPE_CHECKING:
    from plan.scenario import NodePlan


class Activation:
    """A node's activations: ``activation(tick, inputs)`` -> [(graph topic, CDR bytes)]."""

    def __init__(self, plan: NodePlan, node: StepNode,
                 on_note: Callable[[Note], None] | None = None,
                 params_input: ParamsInput | None = None):
        self.plan = plan
        self.node = node
        self.on_note = on_note  # where the node's notes go (dropped when None)
        self.params_input = params_input  # parameter changes from outside, applied first
        self.first = True  # the next activation is the first since the start or a restart
        self.stepped_ns = 0  # perf_counter when the last step returned: the time split only
        self.tails = ConstantTails()  # its constant outputs' bytes (prepare_outputs)

    def __call__(self, tick: Tick, inputs: dict[str, Any]) -> list[tuple[str, bytes]]:
        """Step at ``tick`` on ``inputs`` and return the outputs ready to publish."""
        if self.params_input is not None:
            inputs = self.params_input.apply(self.node, inputs)
        try:
            outputs = self.node.step(tick, inputs)
            self.stepped_ns = time.perf_counter_ns()
        except BaseException:
            take_output_marks()  # a failed step's marks are no later step's
            raise
        finally:
            for text in self.node.take_notes():
                if self.on_note is not None:
                    self.on_note(Note(self.plan.name, tick.index, tick.time_ns, text))
        names, latched, first = self.plan.output_names, self.plan.latched, self.first
        if self.plan.windows or self.plan.relatch or self.plan.output_periods:  # a robot's
            # topics while it is there, a topic of a period of its own at its ticks
            names, latched, first = self.plan.windowed(tick.index, first)
            if getattr(self.node, "holds_outputs", False):  # it holds every topic: the due
                outputs = {own: msg for own, msg in outputs.items() if own in names}
        items = prepare_outputs(self.plan.name, self.plan.declared_outputs, names, tick,
                                outputs, latched, first, self.tails, self.plan.unconsumed)
        self.first = False
        return items

    def restart(self, seed: int) -> None:
        """Back to tick 0: the node reset, its next activation the first (latched outputs
        again), earlier parameter changes forgotten."""
        self.node.reset(seed, self.node.config)
        self.first = True
        if self.params_input is not None:
            self.params_input.forget()
