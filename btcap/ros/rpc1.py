"""Bounded XML-RPC calls to a ROS 1 master or node: every call btcap makes itself (not
rospy's own) goes through :func:`call`.

rosgraph's ``Master`` proxy has no timeout, and rospy sets a process-wide one (60 s) only
once a subscriber connects: a master that accepts the connection and never answers (a
stopped or wedged process) held the caller for ever, and with it the rospy process's
poller (every server's readiness, every type check). Here each call has a bound and fails
in one line naming the URI and the call; it refuses to run on an event loop's thread (it
blocks: a thread's work). The bound is the whole call's, not each read's: a peer that
sends its answer a byte at a time cannot hold the caller longer.
"""

from __future__ import annotations

import http.client
import socket
import sys
import time
import xmlrpc.client
from typing import Any

from btcap.ros.errors import RosError

__all__ = ["CALL_S", "RosCallError", "call"]

#: A bound, not a measure: a master answers in milliseconds.
CALL_S = 2.0


class RosCallError(RosError):
    """A ROS 1 XML-RPC call that got no answer (``answered`` False: no connection, a
    timeout, a broken reply; ``stalled``: the timeout) or a failure code (``answered``
    True: e.g. no such service); ``why`` is the reason alone, the message names the URI
    and the call too."""

    def __init__(self, message: str, why: str, *, answered: bool, stalled: bool = False) -> None:
        super().__init__(message)
        self.why = why
        self.answered = answered
        self.stalled = stalled


class _Bounded(xmlrpc.client.Transport):
    def __init__(self, timeout_s: float) -> None:
        super().__init__()
        self.deadline = time.monotonic() + timeout_s

    def make_connection(self, host: Any) -> http.client.HTTPConnection:
        chost, self._extra_headers, _ = self.get_host_info(host)
        conn = _Connection(chost, self.deadline)
        self._connection = host, conn  # closed by ServerProxy's exit
        return conn


class _Connection(http.client.HTTPConnection):
    """Connects, sends and reads within what is left until ``deadline``."""

    def __init__(self, host: str, deadline: float) -> None:
        super().__init__(host, timeout=_left(deadline))
        self.deadline = deadline

    def connect(self) -> None:
        super().connect()
        sock = _Socket(fileno=self.sock.detach())
        sock.deadline = self.deadline
        self.sock = sock


class _Socket(socket.socket):
    deadline = 0.0

    def sendall(self, data: Any, flags: int = 0) -> None:
        self.settimeout(_left(self.deadline))
        super().sendall(data, flags)

    def recv_into(self, buffer: Any, nbytes: int = 0, flags: int = 0) -> int:
        self.settimeout(_left(self.deadline))
        return super().recv_into(buffer, nbytes, flags)


def _left(deadline: float) -> float:
    """Seconds left until ``deadline``; TimeoutError once none are."""
    left = deadline - time.monotonic()
    if left <= 0:
        raise TimeoutError("timed out")
    return left


def call(uri: str, method: str, *args: Any, timeout_s: float = CALL_S, who: str = "") -> Any:
    """The value of ROS API call ``method(*args)`` at ``uri`` (its ``(code, status,
    value)`` answer's value), within ``timeout_s``; else :class:`RosCallError`. ``who``
    names the peer in the message (default: the ROS 1 master). Blocks: never from a
    thread running an event loop."""
    peer = who or "ROS 1 master"
    _off_loop(peer, uri, method)

    def error(why: str, answered: bool, stalled: bool = False) -> RosCallError:
        message = f"{peer} {uri}: {method}: {why}"
        return RosCallError(message, why, answered=answered, stalled=stalled)

    try:
        with xmlrpc.client.ServerProxy(uri, transport=_Bounded(timeout_s)) as proxy:
            answer: Any = getattr(proxy, method)(*args)
    except TimeoutError:
        raise error(f"no answer within {timeout_s} s", False, True) from None
    except (OSError, ValueError, xmlrpc.client.Error, http.client.HTTPException) as exc:
        text = str(exc).strip().splitlines()
        raise error(text[0] if text else type(exc).__name__, False) from None
    if not (isinstance(answer, list | tuple) and len(answer) == 3):
        raise error(f"answered {str(answer)[:80]!r}, not [code, status, value]", True)
    code, status, value = answer
    if code != 1:
        raise error(f"refused: {status}", True)
    return value


def _off_loop(peer: str, uri: str, method: str) -> None:
    """RosError if this thread runs an asyncio event loop (asyncio is looked up, not
    imported: the rospy process has none)."""
    asyncio = sys.modules.get("asyncio")
    if asyncio is not None and asyncio._get_running_loop() is not None:
        raise RosError(
            f"{peer} {uri}: {method} called on the event loop's thread (it blocks up to "
            "its timeout): run it in a thread"
        )
