"""Replies that arrive: service and action responses sent again until the client can take them.

rmw_fastrtps sends a reply only once the client's reply reader is matched with the server's
reply writer, and waits 100 ms for that; past it, rclpy merely warns "failed to send response
(timeout)" and the reply is gone, while the client waits forever. The server learns of that
reader from discovery, which on a loaded machine can lag the request by seconds (a lost
endpoint announcement is repeated only at the next heartbeat), so a client that called as
soon as it saw the service (``ros2 service call``, any user's rclpy client) sometimes never
got its answer. A timed-out reply was not written, so sending it again cannot duplicate it:
``install`` (called when a run's ROS surface starts) makes every service and action response
of the process retry until the reader is matched, or ``GIVE_UP_S`` passes (then it is logged,
naming what was dropped); in a process that runs cosim through ``orchestrator.api`` that
includes the user's own servers, which gain the same guarantee.
"""

from __future__ import annotations

import functools
import logging
import re
import time
import warnings
from collections.abc import Callable
from typing import Any

GIVE_UP_S = 15.0  # beyond any discovery delay seen; a client gone meanwhile ends it at once
TIMEOUT_WARNING = r"failed to send response \(timeout\)"
log = logging.getLogger("cosim")
_installed = False


def install() -> None:
    """Make every service and action-server response of this process retry (idempotent)."""
    global _installed
    # The native send reports the dropped reply as a warning; as an error it can be caught
    # at the one call that made it (every such call is wrapped below, so none escapes).
    # Set each time: whoever restores the warning filters (pytest does) drops it.
    warnings.filterwarnings("error", message=TIMEOUT_WARNING, category=RuntimeWarning)
    if _installed:
        return
    from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy

    _wrap(_rclpy.Service, "service_send_response")
    for name in ("send_goal_response", "send_cancel_response", "send_result_response"):
        _wrap(_rclpy.ActionServer, name)
    _installed = True


def _wrap(native_type: Any, name: str) -> None:
    send = getattr(native_type, name)
    setattr(native_type, name, delivered(send, name))


def delivered(send: Callable[..., None], what: str,
              give_up_s: float = GIVE_UP_S) -> Callable[..., bool]:
    """``send`` called again while the transport says the client is not matched yet.

    Returns True once the reply went out, False when ``give_up_s`` passed first."""

    @functools.wraps(send)
    def send_until_matched(*args: Any) -> bool:
        deadline = time.monotonic() + give_up_s
        tries = 0
        while True:
            tries += 1
            try:
                send(*args)
            except Exception as error:  # noqa: BLE001 - only a timed-out reply is retried
                timeout = _timed_out(error)
                if timeout is None:
                    raise
                if time.monotonic() < deadline:
                    continue  # each try already waited 100 ms for the match
                log.warning("cosim: a reply (%s) was dropped: its client's reply reader was "
                            "not discovered within %.0f s (%s)", what, give_up_s, timeout)
                return False
            if tries > 1:
                log.debug("cosim: a reply (%s) went out at try %d, once the client's reply "
                          "reader was discovered", what, tries)
            return True

    return send_until_matched


def _timed_out(error: BaseException) -> RuntimeWarning | None:
    """The "failed to send response (timeout)" warning behind ``error``, if that is what it is.

    A native function that returns normally with the warning raised reaches Python as a
    SystemError caused by it, hence the walk along the chain."""
    seen: BaseException | None = error
    while seen is not None:
        if isinstance(seen, RuntimeWarning) and re.search(TIMEOUT_WARNING, str(seen)):
            return seen
        seen = seen.__cause__ or seen.__context__
    return None
