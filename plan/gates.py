"""Which gate serves a foreign program: the one rule every layer reads (``NodePlan.gate``).

A program is *gated* when a gate serves it: ``python`` (cosim's rclpy gate, for a program run
by a Python interpreter) or ``rmw`` (``librmw_cosim_gate.so``, any program on rcl, when
``make install`` built it). Both keep one delivery contract
(docs/how-to/foreign-programs.md): the program takes
each tick's inputs whole and acknowledges each tick with how many messages it published on
each output. A program no gate serves reads the run's topics directly (ungated).
"""

from __future__ import annotations

import sys
from pathlib import Path

from plan.robots import topic_token

PYTHON_GATE, RMW_GATE = "python", "rmw"
RMW_GATE_NAME = "rmw_cosim_gate"
PYTHONS = ("python", "python3")


def is_python_command(command: list[str]) -> bool:
    """Whether the command runs a Python interpreter (so the Python gate can ride in it)."""
    first = command[0]
    return (first in PYTHONS or Path(first).name.startswith("python")
            or first.endswith(".py") or first == sys.executable)


def rmw_gate_library() -> Path:
    """Where ``make install`` puts the RMW gate (tools/build_native.py)."""
    return Path(sys.prefix) / "lib" / f"lib{RMW_GATE_NAME}.so"


def gate_for(command: list[str], wanted: str) -> str | None:
    """The gate that serves a program with this command and ``params.gate`` (``auto``:
    python for a Python program, rmw for any other): 'python', 'rmw', or None when the RMW
    gate is wanted but not built (not x86-64)."""
    if wanted == "auto":
        wanted = PYTHON_GATE if is_python_command(command) else RMW_GATE
    if wanted == RMW_GATE and not rmw_gate_library().is_file():
        return None
    return wanted


FOREIGN_OUTPUT_RULE = ("a gated foreign program may publish any number of messages per "
                       "tick on each output; its consumers see the latest one at or before "
                       "the scheduled producer tick (none before its first message); the "
                       "bag and the digest hold every message, in order")


def feed_prefix(name: str) -> str:
    """The private topic prefix of a foreign program's feed: '/cosim/feed/<node>/'."""
    return f"/cosim/feed/{topic_token(name)}/"


def ack_topic(name: str) -> str:
    """Where a gated program acknowledges each tick taken, with its message counts."""
    return feed_prefix(name) + "taken"
