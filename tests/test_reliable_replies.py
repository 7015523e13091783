"""A reply the transport could not send yet (the client's reply reader not discovered) is sent
again until it goes out: rclpy alone drops it with a warning and the client waits forever."""

import warnings

import pytest

from orchestrator.ros_surface import reliable_replies
from orchestrator.ros_surface.reliable_replies import TIMEOUT_WARNING, delivered


class NativeSend:
    """Stands in for rclpy's native send: warns "failed to send response (timeout)" the
    first ``misses`` times, as rmw_fastrtps does while the client's reader is unmatched."""

    def __init__(self, misses: int, as_system_error: bool = False):
        self.misses = misses
        self.as_system_error = as_system_error
        self.sent: list[tuple] = []
        self.tries = 0

    def __call__(self, *args):
        self.tries += 1
        if self.tries <= self.misses:
            warning = RuntimeWarning("failed to send response (timeout): client will not "
                                     "receive response, at ./src/rmw_response.cpp:164")
            if self.as_system_error:  # how a pybind function returning with it set reaches us
                raise SystemError("returned a result with an exception set") from warning
            raise warning
        self.sent.append(args)


@pytest.mark.parametrize("as_system_error", [False, True])
def test_a_timed_out_reply_is_sent_again_until_it_goes_out(as_system_error):
    send = NativeSend(misses=3, as_system_error=as_system_error)
    assert delivered(send, "step_simulation")("header", "response") is True
    assert send.tries == 4
    assert send.sent == [("header", "response")]


def test_a_reply_never_matched_is_given_up_and_logged(caplog):
    send = NativeSend(misses=10**9)
    with caplog.at_level("WARNING", logger="cosim"):
        assert delivered(send, "get_simulator_features", give_up_s=0.05)("h", "r") is False
    assert send.sent == []
    assert "get_simulator_features" in caplog.text and "dropped" in caplog.text


def test_other_failures_are_not_retried():
    calls = []

    def broken(*args):
        calls.append(args)
        raise ValueError("bad response")

    with pytest.raises(ValueError, match="bad response"):
        delivered(broken, "x")("h", "r")
    assert len(calls) == 1


def test_install_wraps_rclpy_native_sends_and_turns_the_warning_into_an_error():
    from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy

    reliable_replies.install()
    reliable_replies.install()  # idempotent: wrapped once
    send = _rclpy.Service.service_send_response
    assert not hasattr(send.__wrapped__, "__wrapped__")  # wrapped once
    for name in ("send_goal_response", "send_cancel_response", "send_result_response"):
        assert hasattr(getattr(_rclpy.ActionServer, name), "__wrapped__")
    with pytest.raises(RuntimeWarning, match=TIMEOUT_WARNING):
        warnings.warn("failed to send response (timeout): x", RuntimeWarning, stacklevel=1)
