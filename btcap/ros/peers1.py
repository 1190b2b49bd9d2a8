"""The types of a ROS 1 client's peers, for the robot's rospy process
(:mod:`btcap.ros.child1`): a client whose peer has another type than its own never
connects to it, and rospy says so only in its log (an action looks like no server, a topic
like no message yet, a service call fails with an md5sum error).

The master keeps one type per topic (the last publisher's registration), so a topic with
publishers of two types looked all one or all the other. Here each publisher of an action's
``NAME/result`` or of a topic is asked its own (the master's ``getSystemState`` names them,
each node's ``getPublications`` says its types): the client's peer counts as of another
type only when every publisher is (``found``: their types), and publishers of another type
beside one of its own (or one that did not say) are ``noted`` (``NODE (TYPE)`` each). A
service's type comes from the header its server answers a probe with: a definite header is
kept per server (a bounded number of them); a probe that got none (a server slow to answer,
a stall) is no verdict, and the server is read again after ``RETRY_S``.

Run on the poller thread only; imports rosgraph (where rospy is) when asked.
"""

from __future__ import annotations

import io
import socket
import time
from collections import OrderedDict
from collections.abc import Callable
from typing import Any

from btcap.ros import rpc1

__all__ = ["KEPT", "RETRY_S", "PeerTypes", "peers_found", "service_found"]

_RESULT = "ActionResult"
#: How long a node has to say its publications (a bound: it answers in milliseconds).
NODE_S = 1.0
#: The servers whose header is kept (a long run sees servers restart on new ports).
KEPT = 256
#: How long before a server whose probe got no header is read again.
RETRY_S = 1.0

#: A call to the master: method, its arguments after the caller id; its value, or
#: :class:`~btcap.ros.rpc1.RosCallError`.
Ask = Callable[..., Any]


class PeerTypes:
    """What each client's peer was last found to be, and the graph as seen this round."""

    def __init__(
        self, caller_id: str, ask: Ask, clock: Callable[[], float] = time.monotonic
    ) -> None:
        self.caller_id = caller_id
        self.ask = ask
        self.clock = clock
        #: The last ``found`` and ``noted`` reported per client (cid): a change is news.
        self.said: dict[int, str] = {}
        self.noted: dict[int, str] = {}
        self._publishers: dict[str, list[str]] | None = None
        self._publications: dict[str, dict[str, str] | None] = {}
        #: A service server's definite answer: (URI, type, md5sum) -> found.
        self._verdicts: OrderedDict[tuple[str, str, str], str] = OrderedDict()
        #: When a server whose probe got no header is read again.
        self._retry: OrderedDict[tuple[str, str, str], float] = OrderedDict()

    def new_round(self) -> None:
        """Ask the master and nodes again at the next question (once per round at most)."""
        self._publishers = None
        self._publications = {}

    def news(self, cid: int, found: str) -> bool:
        """Whether ``found`` differs from what was last said of client ``cid``."""
        if self.said.get(cid, "") == found:
            return False
        self.said[cid] = found
        return True

    def note(self, cid: int, noted: str) -> bool:
        """Whether ``noted`` differs from what was last noted of client ``cid``."""
        if self.noted.get(cid, "") == noted:
            return False
        self.noted[cid] = noted
        return True

    def forget(self, cid: int) -> None:
        self.said.pop(cid, None)
        self.noted.pop(cid, None)

    # -- actions and topics -------------------------------------------------------------
    def publishers(self, topic: str) -> dict[str, str | None]:
        """Each publisher of ``topic`` (by node) and the type it publishes it with, None
        if its node did not say; empty if the master does not answer."""
        if self._publishers is None:
            try:
                state = self.ask("getSystemState")
                self._publishers = {str(t): [str(n) for n in nodes] for t, nodes in state[0]}
            except (rpc1.RosCallError, TypeError, ValueError, IndexError):
                self._publishers = {}  # gone for now: nothing to say this round
        return {node: self._types_of(node).get(topic) for node in self._publishers.get(topic, ())}

    def _types_of(self, node: str) -> dict[str, str]:
        """The topics ``node`` publishes and their types (empty if it does not say)."""
        if node not in self._publications:
            try:
                uri = self.ask("lookupNode", node)
                answer = rpc1.call(
                    uri, "getPublications", self.caller_id, timeout_s=NODE_S, who=f"node {node}"
                )
                self._publications[node] = {str(t): str(k) for t, k in answer}
            except (rpc1.RosCallError, TypeError, ValueError):
                self._publications[node] = None
        return self._publications[node] or {}

    def check(self, kind: str, types: Any, name: str, connected: bool) -> tuple[str, str]:
        """(found, noted) of the peers of client ``kind`` (``action``: its servers, else a
        subscriber's publishers) of ``name`` and ``types`` (an
        :class:`~btcap.ros.interfaces1.Action1`, a message class); ``connected``: to one of
        its own type. ``noted`` is said as one line."""
        if kind == "action":
            ours, role = _result_type(types.Action), "servers"
            peers = self.publishers(f"{name.rstrip('/')}/result")
        else:
            ours, role = str(types._type), "publishers"
            peers = self.publishers(name)
        found, noted = peers_found(ours, peers, connected)
        if kind == "action":  # said as actions: pkg/Name
            found, noted, ours = _action_type(found), _action_type(noted), types.Action._type[:-6]
        if noted:
            noted = (
                f"{'action' if kind == 'action' else 'topic'} {name}: {role} of another type "
                f"than this robot's {ours} (it cannot connect to them): {noted}"
            )
        return found, noted

    # -- services -----------------------------------------------------------------------
    def service(self, types: Any, uri: str, sock: socket.socket) -> str:
        """The type of the service at ``uri``, if not ``types``' (a
        :class:`~btcap.ros.interfaces1.Service1`), read from the header it answers the
        probe just written on ``sock`` with: once per server if it answers, else again
        after RETRY_S (empty till then)."""
        service = types.Service
        key = (uri, str(service._type), str(service._md5sum))
        found = self._verdicts.get(key)
        if found is not None:
            self._verdicts.move_to_end(key)
            return found
        if self._retry.get(key, 0.0) > self.clock():
            return ""
        import rosgraph.network

        try:
            header = rosgraph.network.read_ros_handshake_header(sock, io.BytesIO(), 4096)
        except Exception:  # no header (a timeout, a stall, a reset): no verdict
            header = {}
        if "type" not in header or "md5sum" not in header or header.get("error"):
            _keep(self._retry, key, self.clock() + RETRY_S)
            return ""
        self._retry.pop(key, None)
        found = service_found(service, header)
        _keep(self._verdicts, key, found)
        return found


def _keep(kept: OrderedDict[Any, Any], key: Any, value: Any) -> None:
    """``kept[key] = value``, the least recently kept dropped beyond KEPT entries."""
    kept[key] = value
    kept.move_to_end(key)
    while len(kept) > KEPT:
        kept.popitem(last=False)


def peers_found(ours: str, peers: dict[str, str | None], connected: bool) -> tuple[str, str]:
    """(found, noted) of a client of type ``ours`` whose peers (by node) have the types
    ``peers`` (None: unknown): ``found``, the other types, when every peer has another
    and the client is not ``connected`` to one of its own; else ``noted``, the peers of
    another type as ``NODE (TYPE)``, if any. Both empty when no peer disagrees."""
    others = {node: kind for node, kind in peers.items() if kind not in (None, ours, "*")}
    if not others:
        return "", ""
    if len(others) == len(peers) and not connected:
        return ", ".join(sorted({str(kind) for kind in others.values()})), ""
    return "", ", ".join(f"{node} ({kind})" for node, kind in sorted(others.items()))


def _result_type(action: Any) -> str:
    """``pkg/NameActionResult`` of genpy's ``pkg/NameAction`` class."""
    return str(action._type) + _RESULT[len("Action") :]


def _action_type(text: str) -> str:
    """``text`` with each ``pkg/NameActionResult`` said as its action, ``pkg/Name``."""
    return text.replace(_RESULT, "")


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
