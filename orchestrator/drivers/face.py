"""The one face of the run's drivers: what a driver is given (``RunContext``), what it gives
back (``LoopResult``) and the points at which what a run carries beside its ticks (the live
view, and what comes next) attaches (``Attachment``), the same for every driver.

A driver runs a scenario's ticks one way: in this process (``drivers.in_process``) or over a
transport with a process per node or group (``drivers.multi_process``). ``Driver.drive`` is
the sequence every driver follows: start, serve (the run's control exists, clients may
connect), ready (the first tick is next), loop. Each attachment hears those steps from
every driver alike and so is wired once. Nothing here imports rclpy or zenoh (node
processes are forked after this module is loaded).
"""

from __future__ import annotations

import contextlib
import os
import time
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

from orchestrator.lockstep.loop_result import LoopResult
from plan.options import RunOptions
from plan.run_paths import RunPaths
from plan.scenario import Scenario
from runtime.arrivals import Arrivals, Replay

OnTick = Callable[[int], None]
"""Called with each tick index once the tick is decided (progress bars)."""

Observer = Callable[[int, str, list[tuple[str, bytes]]], None]
"""Called after an activation with (tick, node, [(topic, bytes)])."""

Offer = Callable[[str, bytes], None]
"""Takes one message of the run's traffic: (topic, CDR bytes), /clock included."""


@dataclass
class RunContext:
    """What a driver is given: the run, its hooks and the resources it holds.

    ``outcome`` is the run's ``orchestrator.execute.RunOutcome`` (start and loop times, node
    statistics, what the live endpoints did). ``on_tick`` (every driver calls it once a tick
    is decided) and ``observers`` (each activation's outputs, where the driver steps the
    nodes itself: in-process; a multi-process run's traffic reaches attachments through
    ``Driver.feed``) are lists that attachments add to before the loop starts; pacing is
    the loop's own (``orchestrator.lockstep.pace.pace_of``, from the options, in both
    loops). ``control`` and ``services`` are the run's RunControl and simulation services,
    where the driver serves them (None otherwise).
    ``resources`` holds what the run opened, released in reverse order when the drive ends.
    """

    scenario: Scenario
    paths: RunPaths
    options: RunOptions
    outcome: Any
    started: float  # time.monotonic() when the run began (start deadline, start_s)
    external: Arrivals | Replay | None = None
    on_tick: list[OnTick] = field(default_factory=list)
    observers: list[Observer] = field(default_factory=list)
    attachments: list[Attachment] = field(default_factory=list)
    control: Any = None
    services: Any = None
    resources: contextlib.ExitStack = field(default_factory=contextlib.ExitStack)

    def ticked(self) -> OnTick | None:
        """One callable for every ``on_tick`` hook, in order (None when there is none)."""
        return _in_order(self.on_tick)

    def observed(self) -> Observer | None:
        """One callable for every observer, in order (None when there is none)."""
        return _in_order(self.observers)

    def nodes_starting(self) -> None:
        """Tell the attachments that node processes are starting (threads may start now)."""
        for attachment in self.attachments:
            attachment.nodes_starting(self)


class Attachment(Protocol):
    """What a run carries beside its ticks, told of each step of every driver's drive."""

    def nodes_starting(self, ctx: RunContext) -> None:
        """Node processes were started and are coming up (drivers that start processes
        say so, before they wait for them): prepare meanwhile."""

    def serving(self, ctx: RunContext, driver: Driver) -> None:
        """The run's control exists (``ctx.control``, ``ctx.services``, or none); clients
        may connect from here on."""

    def ready(self, ctx: RunContext, driver: Driver) -> None:
        """Every node is ready; the first tick is next (``driver.feed`` offers the run's
        traffic from here on)."""


class Driver(ABC):
    """One way to run a scenario's ticks, behind the face every driver shares."""

    control_later = False  # whether the run's control comes after clients may connect

    def drive(self, ctx: RunContext) -> LoopResult:
        """Run the scenario's ticks: start, serve, ready, loop; the run's resources are
        released (in reverse order) whatever happens."""
        with ctx.resources:
            self.start(ctx)
            for attachment in ctx.attachments:
                attachment.serving(ctx, self)
            self.wait_ready(ctx)
            for attachment in ctx.attachments:
                attachment.ready(ctx, self)
            result = self.loop(ctx)
        self.ended(ctx)
        return result

    @abstractmethod
    def start(self, ctx: RunContext) -> None:
        """Start what runs the nodes; set ``ctx.control`` and ``ctx.services`` where the
        driver serves them."""

    @abstractmethod
    def wait_ready(self, ctx: RunContext) -> None:
        """Return once every node is ready for its first tick; the outcome's start times
        are set by now (here or in ``start``)."""

    @abstractmethod
    def loop(self, ctx: RunContext) -> LoopResult:
        """Run the ticks (``ctx.on_tick``, ``ctx.observers``, ``ctx.control``); set the
        outcome's loop time; the loop's result."""

    def ended(self, ctx: RunContext) -> None:  # noqa: B027 - a hook, optional
        """After a loop that returned, once the run's resources are released."""

    @abstractmethod
    def feed(self, ctx: RunContext, offer: Offer) -> None:
        """Offer the run's traffic (every topic and /clock) to ``offer`` from the first
        tick on, as the run goes; called before ``loop``."""


def _in_order(hooks: list[Callable]) -> Callable | None:
    if not hooks:
        return None
    if len(hooks) == 1:
        return hooks[0]
    hooks = list(hooks)

    def every(*args) -> None:
        for hook in hooks:
            hook(*args)
    return every


def since_process_start() -> float | None:
    """Seconds since this process was created (the command, when run from the CLI), from
    the kernel's start time of the process and the boot-time clock (Linux; else None)."""
    try:
        with open("/proc/self/stat") as stat:
            after_name = stat.read().rpartition(")")[2].split()
        started = int(after_name[19]) / os.sysconf("SC_CLK_TCK")  # field 22: starttime
        return time.clock_gettime(time.CLOCK_BOOTTIME) - started
    except (OSError, ValueError, IndexError, AttributeError):
        return None
