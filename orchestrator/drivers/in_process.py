"""The in-process driver: every node's step class in this process, in schedule order, no
transport (``orchestrator.lockstep.inprocess.run_in_process``, the reference). The driver
records each node's outputs into its part file and what entered from outside into the
external node's; its observers see every activation, its ``on_tick`` hooks every tick."""

from __future__ import annotations

import time

from orchestrator.drivers.face import Driver, Offer, RunContext, since_process_start
from orchestrator.lockstep.loop_result import LoopResult
from plan.roles import NodeRole
from runtime.arrivals import Arrivals
from runtime.recording import PartWriter


class InProcessDriver(Driver):
    """Runs the scenario in this process; serves no run control."""

    def start(self, ctx: RunContext) -> None:
        """The start times (nothing to wait for), the nodes' part writers and the external
        node's arrivals, recorded as they are taken."""
        from orchestrator.proxies.arrivals_record import recording

        ctx.outcome.start_s = time.monotonic() - ctx.started
        ctx.outcome.command_to_first_tick_s = since_process_start()
        self.writers = {name: PartWriter(ctx.paths.part(name)) for name in ctx.scenario.nodes}
        for writer in self.writers.values():
            ctx.resources.callback(writer.close)
        external = ctx.external
        self.arrivals = recording(external.take if isinstance(external, Arrivals) else external,
                                  self.writers.get(_external_name(ctx)))
        ctx.observers.insert(0, self._record)

    def _record(self, k: int, name: str, items: list[tuple[str, bytes]]) -> None:
        self.writers[name].write(k, items)

    def wait_ready(self, ctx: RunContext) -> None:
        """Nothing to wait for: the nodes are built by the loop."""

    def loop(self, ctx: RunContext) -> LoopResult:
        """``run_in_process`` with the run's observers, tick hooks, arrivals and pace."""
        from orchestrator.lockstep.inprocess import run_in_process
        from orchestrator.lockstep.pace import pace_of

        return run_in_process(ctx.scenario, ctx.observed(), ctx.ticked(), self.arrivals,
                              pace_of(ctx.options))

    def ended(self, ctx: RunContext) -> None:
        """The loop's time: from the start times to the writers closed."""
        ctx.outcome.loop_s = time.monotonic() - ctx.started - ctx.outcome.start_s

    def feed(self, ctx: RunContext, offer: Offer) -> None:
        """Each activation's outputs as the loop makes them, and /clock once a tick is done
        (an in-process run has no /clock of its own)."""
        from runtime.protocol import CLOCK_TOPIC, encode_clock

        sched = ctx.scenario.schedule

        def observe(_tick: int, _name: str, items: list[tuple[str, bytes]]) -> None:
            for topic, data in items:
                offer(topic, data)

        def on_tick(tick: int) -> None:
            offer(CLOCK_TOPIC, encode_clock(sched.time_ns(tick)))

        ctx.observers.append(observe)
        ctx.on_tick.append(on_tick)


def _external_name(ctx: RunContext) -> str | None:
    return next((n for n, p in ctx.scenario.nodes.items() if p.role is NodeRole.ORCHESTRATOR),
                None)
