"""What every ROS tree node shares: finding the robot's bridge, the timeout ports, the
QoS ports, and failing with the reason in ``node.error``."""

from __future__ import annotations

import time
from typing import Any, ClassVar

from msgspec import Meta

from btcap.bt.node import Leaf
from btcap.bt.ports import Port
from btcap.bt.state import State
from btcap.ros.client import RosBridge
from btcap.ros.errors import RosError
from btcap.ros.versions import ROS2, Types
from btcap.team.rossettings import Qos

__all__ = ["QOS_OPTIONS", "RosLeaf", "now", "qos_of"]

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

    __slots__ = ("_bridge", "_waiting_since")
    #: The interface kind the type option names: ``action``, ``srv`` or ``msg``.
    KIND: ClassVar[str] = "msg"
    #: The ROS version's interface functions when no bridge is given (ROS 1's node types,
    #: btcap.ros.nodes1, hold ROS1); a given bridge's own otherwise.
    TYPES: ClassVar[Types] = ROS2

    def __init__(self, *args: Any, bridge: RosBridge | None = None, **kwargs: Any) -> None:
        self._bridge = bridge
        self._waiting_since: float | None = None
        super().__init__(*args, **kwargs)

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

    def _server_missing(self, ready: bool) -> State | None:
        """None once the server is ready; until then RUNNING, and FAILED (saying so) once
        it was missing longer than ``wait_for_server_timeout`` (else ``server_timeout``)."""
        if ready:
            self._waiting_since = None
            return None
        t = now()
        if self._waiting_since is None:
            self._waiting_since = t
        limit = self.options["wait_for_server_timeout"] or self.options["server_timeout"]
        if t - self._waiting_since > limit:
            self._waiting_since = None
            return self.failed(f"{self._what()}: no server after {limit} s")
        return _RUNNING

    def failed(self, why: str) -> State:
        """FAILED, with ``why`` (one line) as the node's error."""
        self.error = RosError(f"{type(self).__name__} {self.path!r}: {why}")
        return _FAILED
