"""What every ROS tree node shares: finding the robot's bridge, the name port
(``action_name``, ``service_name``, ``topic_name``), the timeout and QoS options, telling
the tree there is news, and failing with the reason in ``node.error``.

The name is an input port, as in BehaviorTree.ROS2: a literal (``action_name="navigate"``
in XML, ``inputs={"action_name": ...}`` in YAML, the ``action_name=`` keyword in Python)
or read from a blackboard entry or a wire (``action_name="{nav_action}"``), resolved in
the robot's namespace. It is read when a node starts its work (a goal, a call, a wait,
a publisher or subscription); a change while the work runs takes effect at the next.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable
from typing import Any, ClassVar

from msgspec import Meta

from btcap.bt.node import Leaf
from btcap.bt.ports import Port
from btcap.bt.state import State
from btcap.ros.client import RosBridge
from btcap.ros.errors import RosError
from btcap.ros.versions import ROS2, Types
from btcap.ros.waker import Waker
from btcap.team.rossettings import Qos

__all__ = [
    "QOS_OPTIONS",
    "SERVER_OPTIONS",
    "RosLeaf",
    "give",
    "name_input",
    "now",
    "qos_of",
    "seconds",
    "seconds_options",
]

_FAILED = State.FAILED
_RUNNING = State.RUNNING

#: The clock of ROS timeouts: ROS runs on the wall, whatever the tree's clock speed-up.
now = time.monotonic

_SECONDS = Meta(gt=0)

#: Per-node QoS (topics); None: the robot's default (``ros.qos`` of its file).
QOS_OPTIONS: dict[str, Any] = {
    "reliability": Port(str | None, None, "`reliable` or `best_effort`; null: the robot's default"),
    "durability": Port(
        str | None, None, "`volatile` or `transient_local`; null: the robot's default"
    ),
    "depth": Port(int | None, None, "history depth; null: the robot's default", Meta(ge=1)),
}


def seconds(description: str, default: float | None) -> Port:
    """An option of seconds (``server_timeout``); None allowed where the default is."""
    kind: Any = float if default is not None else float | None
    return Port(kind, default, description, _SECONDS)


#: How long a node waits for its server to appear in the ROS graph (DDS discovery) before
#: it fails: tens of milliseconds on an idle machine, but over 1.5 s was seen with 2 cores
#: at load 12 (BehaviorTree.ROS2's 0.5 s, or our former 1 s, failed there); 10 s still
#: fails a server that is really missing within a bound a person waits for.
WAIT_FOR_SERVER_S = 10.0
#: How long a node waits for the answer of a server it found: a goal's acceptance, or a
#: service's response (which includes the service's own work; set it per node).
SERVER_S = 5.0


def name_input(port: str, what: str) -> dict[str, Port]:
    """The INPUTS of a ROS node class: its name port (its interface's fields are added
    per node, from its type)."""
    return {port: Port(str, description=f"the {what}'s name, in the robot's namespace")}


def seconds_options(what: str) -> dict[str, Port]:
    return {
        "wait_for_server_timeout": seconds(
            f"how long to wait for the {what} to appear in the ROS graph (discovery)",
            WAIT_FOR_SERVER_S,
        ),
        "server_timeout": seconds(f"how long to wait for the {what}'s answer", SERVER_S),
    }


SERVER_OPTIONS = seconds_options("server")


def qos_of(node: Leaf, bridge: RosBridge) -> Any:
    """The node's QoS options over the robot's defaults, as an rclpy QoSProfile."""
    base = bridge.settings.qos
    opts = node.options
    try:
        q = Qos(
            reliability=opts["reliability"] or base.reliability,
            durability=opts["durability"] or base.durability,
            depth=opts["depth"] or base.depth,
        )
        import msgspec

        q = msgspec.convert(msgspec.structs.asdict(q), Qos)
    except (ValueError, TypeError) as exc:
        raise RosError(f"node {node.path!r}: QoS: {exc}") from None
    return bridge.qos(q)


class RosLeaf(Leaf):
    """A leaf that talks to ROS through its robot's :class:`~btcap.ros.client.RosBridge`:
    the one given as ``bridge=`` (Python), else the one its tree's actor system provides
    (an agent with a ``ros:`` block)."""

    __slots__ = ("_bridge", "_news", "_waiting_for", "_waiting_since")
    #: The interface kind the type option names: ``action``, ``srv`` or ``msg``.
    KIND: ClassVar[str] = "msg"
    #: The input port naming the action, service or topic.
    NAME_PORT: ClassVar[str] = "topic_name"
    #: The ROS version's interface functions when no bridge is given (ROS 1's node types,
    #: btcap.ros.nodes1, hold ROS1); a given bridge's own otherwise.
    TYPES: ClassVar[Types] = ROS2

    def __init__(self, *args: Any, bridge: RosBridge | None = None, **kwargs: Any) -> None:
        self._bridge = bridge
        self._waiting_since: float | None = None
        self._waiting_for = ""
        self._news: Callable[[bool], None] | None = None
        named = kwargs.pop(self.NAME_PORT, None)  # Python's shorthand for the input
        super().__init__(*args, **kwargs)
        if named is not None:
            self.set_input(self.NAME_PORT, named)

    def name_port(self) -> dict[str, Port]:
        """The name's input port (the class's INPUTS), for :meth:`declare_ports`."""
        return dict(type(self).INPUTS)

    def with_name_port(self, fields: dict[str, Port], of: str) -> dict[str, Port]:
        """``fields`` (an interface's, as inputs) after the name port; RosError if one of
        them is called like it."""
        if self.NAME_PORT in fields:
            raise RosError(
                f"node {self.name!r}: {of} has a field {self.NAME_PORT!r}, which is the "
                f"name port of {type(self).__name__}; it cannot be an input too"
            )
        return {**self.name_port(), **fields}

    def literal_name(self) -> str | None:
        """The name when it is a constant (not read from a wire or the blackboard)."""
        port = self.NAME_PORT
        if any(k == port for k, _, _ in self._pulls or ()):
            return None
        value = self.inputs.get(port)
        return value if isinstance(value, str) and value else None

    def ros_name(self) -> str:
        """The name the input holds now, resolved in the robot's namespace; RosError
        naming the node and the port when it is no name."""
        value = self.inputs.get(self.NAME_PORT)
        if not isinstance(value, str) or not value:
            got = f"{type(value).__name__} {value!r}" if value is not None else "nothing"
            raise RosError(
                f"{type(self).__name__} {self.path!r} input {self.NAME_PORT!r}: expected "
                f"a non-empty ROS name (str), got {got}"
            )
        try:
            return self.bridge.resolve(value)
        except RosError as exc:
            raise RosError(
                f"{type(self).__name__} {self.path!r} input {self.NAME_PORT!r}: {exc}"
            ) from None

    def news(self) -> Callable[[bool], None]:
        """What the bridge's executor thread calls when there is news for this node
        (``news(minor)``; feedback is minor): its tree is ticked soon (a
        :class:`~btcap.ros.waker.Waker` hands it to the event loop the node ticks on),
        and the bridge's own hook (:meth:`RosBridge.wake_on`) is called. On the tick."""
        hook = self._news
        if hook is None:
            bridge = self.bridge
            waker: Waker | None = None
            try:
                loop = asyncio.get_running_loop()
            except RuntimeError:  # ticked outside a loop: read at the next tick
                loop = None
            if loop is not None and self._tree is not None and bridge.nudges:
                waker = Waker(self._tree, loop)

            def hook(minor: bool = False) -> None:  # executor thread
                if waker is not None:
                    waker(minor)
                if not minor:
                    bridge.wake()

            self._news = hook
        return hook

    @property
    def types(self) -> Types:
        """The interface functions of the node's ROS version."""
        return self._bridge.types if self._bridge is not None else self.TYPES

    @property
    def bridge(self) -> RosBridge:
        """The robot's bridge; RosError naming the node when there is none."""
        if self._bridge is None:
            system = self._tree.system if self._tree is not None else None
            self._bridge = RosBridge.of(system)
            if self._bridge is None:
                raise RosError(
                    f"node {self.path!r} ({type(self).__name__}): no ROS bridge: give the "
                    "robot's agent file a `ros:` block, or pass bridge= / call "
                    "RosBridge.provide(system)"
                )
        if self._bridge.conflict is not None:
            raise RosError(f"node {self.path!r}: {self._bridge.conflict}")
        return self._bridge

    def _what(self) -> str:
        """The ROS interface this node talks to, for its errors."""
        return repr(self.path)

    def _server_missing(self, ready: bool, name: str) -> State | None:
        """None once the server of ``name`` is ready; until then RUNNING, and FAILED
        (saying so) once it was missing longer than ``wait_for_server_timeout``. A name
        changed while waiting restarts the wait for the new one."""
        if ready:
            self._waiting_since = None
            return None
        t = now()
        if self._waiting_since is None or self._waiting_for != name:
            self._waiting_since = t
            self._waiting_for = name
        limit = self.options["wait_for_server_timeout"]
        if t - self._waiting_since > limit:
            self._waiting_since = None
            return self.failed(
                f"{self._what()}: no server within wait_for_server_timeout {limit} s"
            )
        return _RUNNING

    def peer_type(self, client: Any) -> str | None:
        """The type of ``client``'s peers (its server, its topic's publishers or
        subscribers) when none has its own, as last found; the bridge tells of any peer of
        another type once per node (ROS 2: :mod:`btcap.ros.peers`)."""
        return self.bridge.mismatch(client, f"{type(self).__name__} {self.path!r}")

    def mismatched(self, client: Any, what: str, expected: str) -> State | None:
        """FAILED, saying so, when the peers of ``client`` (its server, or its topic's
        publishers) have another type than ``expected`` (none has it); None when none was
        seen. ``what`` names the action, service or topic."""
        found = self.peer_type(client)
        if found is None:
            return None
        self._waiting_since = None
        return self.failed(f"{what}: type mismatch: expected {expected}, found {found}")

    def failed(self, why: str) -> State:
        """FAILED, with ``why`` (one line) as the node's error."""
        self.error = RosError(f"{type(self).__name__} {self.path!r}: {why}")
        return _FAILED


def give(bridge: RosBridge, tree: Any) -> int:
    """Let the ROS nodes of ``tree`` (a Tree, Subtrees' inner trees too) that have no
    bridge use ``bridge`` (``btcap tree run --ros``); how many there are."""
    count = 0
    for node in tree.nodes():
        inner = getattr(node, "inner", None)
        if inner is not None:
            count += give(bridge, inner)
        elif isinstance(node, RosLeaf):
            count += 1
            if node._bridge is None:
                node._bridge = bridge
    return count
