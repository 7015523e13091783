"""The requests the manager's face puts on the switch topic (``/controller_manager/cosim/
switch``, std_msgs/String), one a line: ``#<id> <body>``, the id counting up from 1 in each
run; the body is a switch (``-name`` deactivates, ``+name`` activates, space-separated) or
``load:name``, ``unload:name``, ``configure:name``. Requests put within one tick enter
together, in order. The node reports the newest request it handled (metric ``request``) and
each one it refused at that tick (``refused:<id>``, the reason in a note), which the face
answers from."""

from __future__ import annotations

from nodes.ros2_control.interface import HardwareState
from nodes.ros2_control.manager import ControllerManager

LIFECYCLE_VERBS = ("load", "unload", "configure")  # 'load:name'


def request_lines(data: str) -> list[tuple[int | None, str]]:
    """(id, body) of every line (id None: a line without ``#<id>``)."""
    out: list[tuple[int | None, str]] = []
    for line in data.splitlines():
        head, _, rest = line.strip().partition(" ")
        if head.startswith("#") and head[1:].isdigit():
            out.append((int(head[1:]), rest.strip()))
        elif line.strip():
            out.append((None, line.strip()))
    return out


def apply_request(manager: ControllerManager, body: str, state: HardwareState
                  ) -> tuple[dict[str, float], str | None]:
    """Do request ``body``: the commands a switch leaves, and why it was refused (the
    note's text) or None."""
    words = body.split()
    verb, _, name = body.partition(":")
    if verb in LIFECYCLE_VERBS and len(words) == 1:
        problem = manager.lifecycle(verb, name)
        return {}, f"{verb}_controller refused: {problem}" if problem else None
    bad = [w for w in words if not (w[:1] in "+-" and len(w) > 1)]
    if bad or not words:
        return {}, (f"switch_controller refused: {body!r}: {bad[0]!r} is not '+name' "
                    "(activate) or '-name' (deactivate)" if bad else
                    "switch_controller refused: an empty request")
    activate = [w[1:] for w in words if w.startswith("+")]
    deactivate = [w[1:] for w in words if w.startswith("-")]
    done, problem = manager.switch(activate, deactivate, state)
    return done.commands, f"switch_controller refused: {body!r}: {problem}" if problem else None
