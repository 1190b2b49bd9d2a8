"""The types of a ROS 2 node's peers on its name, read from rclpy's graph, for
:class:`~btcap.ros.client.RosBridge` (ROS 1's counterpart: :mod:`btcap.ros.peers1`).

Two ROS 2 endpoints of one name but different types never match, and nobody says so: an
action or service client of type A finds no server while only a server of type B serves
the name, a subscriber of A gets nothing from a publisher of B, a publisher of A reaches
no subscriber of B. The graph knows each endpoint's type: an action server publishes
``NAME/_action/feedback`` as ``pkg/action/Name_FeedbackMessage``, a service's servers are
listed by node, a topic's publishers and subscribers carry their type.

A tree node asks (:meth:`PeerTypes.ask`, on the tick) while it waits for its server or a
message, and at each tick of a publisher; so does a robot's bid for a capability while a
server its implementation needs is not ready (:func:`~btcap.ros.capability.with_ros`), and
a cost reading a topic that has no message yet (:meth:`RosBridge.latest
<btcap.ros.client.RosBridge.latest>`). The answer is the one last found: the graph is
read on the bridge's executor thread, never on the event loop, at a node's first question
and then at most every :data:`CHECK_S` per name. A peer of another type is told once per
node and type, as a :class:`~btcap.ros.errors.RosTypeWarning` and a log line
(``btcap.ros.type_mismatch``) naming the node, the name, the type expected and the one
found. The answer to the node is that type only while no peer of its own type is there:
a goal, request or wait that can never be answered fails then, saying so.
"""

from __future__ import annotations

import contextlib
import math
import threading
import time
import warnings
import weakref
from collections.abc import Callable
from typing import Any

from btcap.ros.errors import RosTypeWarning
from btcap.transports.log import get_logger

__all__ = ["CHECK_S", "PeerTypes", "endpoint", "tell", "type_name"]

log = get_logger(__name__)

#: How often, at most, the graph is read again for one name while nodes ask of it.
CHECK_S = 1.0
#: An answer older than this (nobody asked for a while) is no answer: read the graph anew.
_FRESH_S = 3 * CHECK_S
#: Names and askers remembered: whatever names trees read from their blackboards, the
#: bridge holds a bounded amount.
_NAMES = 256
_ASKERS = 64

_FEEDBACK = "_FeedbackMessage"

#: What a peer of another type does to the node, by the node's role.
_EFFECT = {
    "action": ("action", "an action server of that type never answers this node's goals"),
    "service": ("service", "a service server of that type never answers this node's calls"),
    "subscription": ("topic", "none of that publisher's messages reach this node"),
    "publisher": ("topic", "none of this node's messages reach that subscriber"),
}

now = time.monotonic


def type_name(cls: Any, kind: str) -> str:
    """``pkg/kind/Name`` of a rosidl class (``test_msgs.action._fibonacci.Fibonacci``), as
    the graph names it."""
    return f"{cls.__module__.split('.', 1)[0]}/{kind}/{cls.__name__}"


def endpoint(client: Any) -> tuple[str, str, str] | None:
    """(role, name, type) of an rclpy ActionClient, service Client, Subscription or
    Publisher; None for anything else."""
    from rclpy.publisher import Publisher
    from rclpy.subscription import Subscription

    if isinstance(client, Subscription):
        return "subscription", client.topic_name, type_name(client.msg_type, "msg")
    if isinstance(client, Publisher):
        return "publisher", client.topic_name, type_name(client.msg_type, "msg")
    action = getattr(client, "_action_type", None)
    if action is not None:
        return "action", str(client._action_name), type_name(action, "action")
    service = getattr(client, "srv_type", None)
    if service is not None:
        return "service", str(client.srv_name), type_name(service, "srv")
    return None


class _Name:
    """What is known of the peers of one (role, name, type)."""

    __slots__ = (
        "asked_at",
        "askers",
        "checked_at",
        "effects",
        "found",
        "name",
        "others",
        "ours",
        "pending",
        "role",
    )

    def __init__(self, role: str, name: str, ours: str) -> None:
        self.role = role
        self.name = name
        self.ours = ours
        #: The peers' other types, and them in one phrase when no peer has ours (else None).
        self.others: list[str] = []
        self.found: str | None = None
        self.checked_at: float | None = None
        self.asked_at = 0.0
        self.pending = False
        #: The nodes that asked, each with the types it was told of.
        self.askers: dict[str, set[str]] = {}
        #: What a peer of another type does to an asker, where not its role's (a bid's).
        self.effects: dict[str, str] = {}


class PeerTypes:
    """The peer types of a bridge's clients; ``submit(fn, arg)`` runs ``fn(arg)`` on the
    bridge's executor thread (``Executor.create_task``), ``node`` is its rclpy node."""

    def __init__(self, node: Any, submit: Callable[[Callable[[_Name], None], _Name], Any]):
        self._node = node
        self._submit = submit
        self._names: dict[tuple[str, str, str], _Name] = {}
        #: Each client's endpoint(), found once (reading it costs more than the rest).
        self._keys: weakref.WeakKeyDictionary[Any, tuple[str, str, str] | None] = (
            weakref.WeakKeyDictionary()
        )
        self._lock = threading.Lock()
        #: Graph reads done (for tests: bounded, not one per tick).
        self.checks = 0

    def ask(self, client: Any, asker: str, effect: str = "") -> str | None:
        """(On the tick) the type of ``client``'s peers when none has the client's own,
        as last found; reads the graph anew, off the loop, at ``asker``'s first question
        and at most every :data:`CHECK_S`. ``asker`` names the node in what is told, and
        ``effect`` what that does to it (by default: to a node of the client's role)."""
        try:
            key = self._keys[client]
        except KeyError:
            key = self._keys[client] = endpoint(client)
        except TypeError:  # not weakly referable (no rclpy client)
            key = endpoint(client)
        if key is None:
            return None
        t = now()
        with self._lock:
            entry = self._names.get(key)
            if entry is None:
                entry = self._names[key] = _Name(*key)
                if len(self._names) > _NAMES:
                    self._forget()
            entry.asked_at = t
            age = t - entry.checked_at if entry.checked_at is not None else math.inf
            fresh = age < _FRESH_S  # else asked of again after a while: wait for news
            new = asker not in entry.askers and len(entry.askers) < _ASKERS
            known = entry.others if new and fresh else []
            if new:  # told at once of what is known, and the graph read anew
                entry.askers[asker] = set(known)
                if effect:
                    entry.effects[asker] = effect
            due = not entry.pending and (new or age >= CHECK_S)
            entry.pending = entry.pending or due
            found = entry.found if fresh else None
        if known:
            _tell(entry, asker, ", ".join(known))
        if due:
            try:
                self._submit(self._check, entry)
            except Exception:  # the executor is shutting down: nothing more to learn
                entry.pending = False
        return found

    def _forget(self) -> None:
        """Drop the name asked of longest ago but the one just added (under the lock)."""
        key = min(list(self._names)[:-1], key=lambda k: self._names[k].asked_at)
        del self._names[key]

    # executor thread
    def _check(self, entry: _Name) -> None:
        try:
            types: set[str] | None = self._types(entry)
        except Exception:  # the node is being destroyed: nothing to say
            types = None
        told: list[tuple[str, list[str]]] = []
        with self._lock:
            self.checks += 1
            entry.pending = False
            entry.checked_at = now()
            if types is None:
                return
            others = entry.others = sorted(types - {entry.ours})
            entry.found = ", ".join(others) if others and entry.ours not in types else None
            for asker, said in entry.askers.items():
                new = [t for t in others if t not in said]
                if new:
                    said.update(new)
                    told.append((asker, new))
        for asker, new in told:
            _tell(entry, asker, ", ".join(new))

    def _types(self, entry: _Name) -> set[str]:
        """The types of the peers of ``entry``'s name, as the graph has them now."""
        node = self._node
        role, name = entry.role, entry.name
        if role == "action":  # the servers publish its feedback
            infos = node.get_publishers_info_by_topic(f"{name}/_action/feedback")
            return {_strip(str(i.topic_type)) for i in infos}
        if role == "subscription":
            return {str(i.topic_type) for i in node.get_publishers_info_by_topic(name)}
        if role == "publisher":
            return {str(i.topic_type) for i in node.get_subscriptions_info_by_topic(name)}
        # A service's types are its clients' and servers' alike (this client's among them):
        # only another type there costs a look at the servers, node by node.
        listed = set(dict(node.get_service_names_and_types()).get(name, ()))
        if listed <= {entry.ours}:
            return listed
        servers: set[str] = set()
        for other, namespace in node.get_node_names_and_namespaces():
            try:
                served = node.get_service_names_and_types_by_node(other, namespace)
            except Exception:  # it left meanwhile
                continue
            for service, kinds in served:
                if service == name:
                    servers.update(map(str, kinds))
        return servers


def _strip(feedback: str) -> str:
    """``pkg/action/Name`` of its feedback topic's type ``pkg/action/Name_FeedbackMessage``."""
    return feedback[: -len(_FEEDBACK)] if feedback.endswith(_FEEDBACK) else feedback


def _tell(entry: _Name, asker: str, found: str) -> None:
    """One line for ``asker``: its name has a peer of type ``found`` (either thread)."""
    kind, effect = _EFFECT[entry.role]
    tell(asker, f"{kind} {entry.name}", entry.ours, found, entry.effects.get(asker, effect))


def tell(asker: str, what: str, expected: str, found: str, effect: str) -> None:
    """Say once, as a :class:`~btcap.ros.errors.RosTypeWarning` and the log line
    ``btcap.ros.type_mismatch``, that ``what`` (``action /husky1/navigate``) has a peer of
    type ``found`` where ``asker`` expects ``expected``, and ``effect`` (any thread; the
    caller keeps it to once: ROS 1's bridge, :class:`PeerTypes` here)."""
    log.warning("btcap.ros.type_mismatch", node=asker, name=what, expected=expected, found=found)
    text = f"{asker}: {what}: type mismatch: expected {expected}, found {found}: {effect}"
    # A filter that makes it an error has nobody to raise it to on this thread.
    with contextlib.suppress(Warning):
        where = f"<ros {what.rpartition(' ')[2]}>"
        warnings.warn_explicit(text, RosTypeWarning, where, 0, module="btcap")
