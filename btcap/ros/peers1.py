"""The types of a ROS 1 client's peers, for the robot's rospy process
(:mod:`btcap.ros.child1`): a client whose peer has another type than its own never
connects, and rospy says so only in its log (an action looks like no server, a topic like
no message yet, a service call fails with an md5sum error). The poller asks here, for the
clients that found no peer, which type the peer has: an action server's and a publisher's
from the master's published topics (an action server publishes ``NAME/result`` as
``pkg/NameActionResult``), a service's from the header it answers a probe with. The answer
is one phrase, ``found``: the peer's type, or empty when nothing disagrees.

Run on the poller thread only; imports rosgraph (where rospy is) when asked.
"""

from __future__ import annotations

import io
import socket
from typing import Any

__all__ = ["PeerTypes", "service_found"]

_RESULT = "ActionResult"


class PeerTypes:
    """What each client's peer was last found to be, and the master's view of this round."""

    def __init__(self, caller_id: str) -> None:
        self.caller_id = caller_id
        #: The last ``found`` reported per client (cid): a change is news for the bridge.
        self.said: dict[int, str] = {}
        self._published: dict[str, str] | None = None
        #: A service's peer by client: (the server's URI, what its header said).
        self._services: dict[int, tuple[str, str]] = {}

    def new_round(self) -> None:
        """Ask the master again at the next question (once per round at most)."""
        self._published = None

    def news(self, cid: int, found: str) -> bool:
        """Whether ``found`` differs from what was last said of client ``cid``."""
        if self.said.get(cid, "") == found:
            return False
        self.said[cid] = found
        return True

    def forget(self, cid: int) -> None:
        self.said.pop(cid, None)
        self._services.pop(cid, None)

    def published(self) -> dict[str, str]:
        """The master's published topics and their types (empty if it does not answer)."""
        if self._published is None:
            import rosgraph

            try:
                topics = rosgraph.Master(self.caller_id).getPublishedTopics("")
                self._published = {str(name): str(kind) for name, kind in topics}
            except Exception:  # gone for now: nothing to say this round
                self._published = {}
        return self._published

    def action(self, types: Any, name: str) -> str:
        """The action type the server of action ``name`` serves, if not ``types``' own
        (``types`` is a :class:`~btcap.ros.interfaces1.Action1`)."""
        ours = _result_type(types.Action)
        theirs = self.published().get(f"{name.rstrip('/')}/result")
        if theirs is None or theirs in (ours, "*"):
            return ""
        return theirs[: -len(_RESULT)] if theirs.endswith(_RESULT) else theirs

    def topic(self, types: Any, name: str) -> str:
        """The type topic ``name`` is published with, if not ``types``' (a message class)."""
        theirs = self.published().get(name)
        return "" if theirs is None or theirs in (types._type, "*") else theirs

    def service(self, cid: int, types: Any, uri: str, sock: socket.socket) -> str:
        """The type of the service at ``uri``, if not ``types``' (a
        :class:`~btcap.ros.interfaces1.Service1`), read from the header it answers the
        probe just written on ``sock`` with: read once per server (its URI)."""
        known = self._services.get(cid)
        if known is not None and known[0] == uri:
            return known[1]
        import rosgraph.network

        try:
            header = rosgraph.network.read_ros_handshake_header(sock, io.BytesIO(), 4096)
        except Exception:  # no header (an old server, a stall): nothing to say of it
            header = {}
        found = service_found(types.Service, header)
        self._services[cid] = (uri, found)
        return found


def _result_type(action: Any) -> str:
    """``pkg/NameActionResult`` of genpy's ``pkg/NameAction`` class."""
    return str(action._type) + _RESULT[len("Action") :]


def service_found(service: Any, header: dict[str, str]) -> str:
    """What a service's probe ``header`` says it is, if not genpy's ``service`` class:
    another type, or the same type of another definition (its md5sum); else empty."""
    theirs, md5 = header.get("type"), header.get("md5sum")
    if theirs is None or md5 is None or header.get("error"):
        return ""
    if theirs != service._type:
        return theirs
    if md5 not in (service._md5sum, "*"):
        return f"{theirs} of another definition (md5sum {md5}; this robot's {service._md5sum})"
    return ""
