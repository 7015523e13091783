"""The run's drivers behind one face (``face``): in-process and multi-process."""

from __future__ import annotations

from orchestrator.drivers.face import Driver
from plan.options import RunOptions


def driver_for(options: RunOptions) -> Driver:
    """The driver the run's options ask for: in-process (``--in-process``) or multi-process."""
    if options.in_process:
        from orchestrator.drivers.in_process import InProcessDriver

        return InProcessDriver()
    from orchestrator.drivers.multi_process import MultiProcessDriver

    return MultiProcessDriver()
