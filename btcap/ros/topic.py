"""Topic nodes: RosPublish (once, or at a rate), RosSubscribe (the latest message, or
chosen fields, to outputs; optionally only if fresh) and RosWaitForMessage (running until
a new message arrives).

Port names follow BehaviorTree.ROS2 (``topic_name``); QoS is the robot's default unless
the node sets ``reliability``, ``durability`` or ``depth``. Messages arrive on the
bridge's executor thread, which only keeps the latest and when it came.
"""

from __future__ import annotations

from typing import Any, ClassVar

from msgspec import Meta

from btcap.bt.ports import NO_DEFAULT, Port, normalize_ports
from btcap.bt.state import State
from btcap.ros.base import QOS_OPTIONS, RosLeaf, now, qos_of, seconds
from btcap.ros.errors import RosError

__all__ = ["RosPublish", "RosSubscribe", "RosWaitForMessage"]

_RUNNING = State.RUNNING
_SUCCEEDED = State.SUCCEEDED
_FAILED = State.FAILED

_TOPIC: dict[str, Any] = {
    "topic_type": Port(str, description="e.g. `geometry_msgs/msg/PoseStamped`"),
    "topic_name": Port(str, description="resolved in the robot's namespace"),
    **QOS_OPTIONS,
}


class RosPublish(RosLeaf):
    """Publishes a message made of its inputs: once (SUCCEEDED), or every ``1/rate_hz``
    seconds while ticked (RUNNING until halted)."""

    __slots__ = ("_next_at", "_publisher", "_types")
    OPTIONS: ClassVar[dict[str, Any]] = {
        **_TOPIC,
        "rate_hz": Port(float | None, None, "publish at this rate; null: once", Meta(gt=0)),
    }

    def declare_ports(self) -> None:
        types = self.types
        cls = self._types = types.interface(self.options["topic_type"], "msg")
        field_types, port_type = types.field_types, types.port_type
        self.input_ports = normalize_ports(
            {
                k: Port(port_type(t) | None, None, f"message field ({t})")
                for k, t in field_types(cls).items()
            },
            f"{self.name}.inputs",
        )
        self._publisher: Any = None
        self._next_at = 0.0

    def on_tick(self) -> State:
        bridge = self.bridge
        if self._publisher is None:
            name = bridge.resolve(self.options["topic_name"])
            self._publisher = bridge.running().create_publisher(
                self._types, name, qos_of(self, bridge)
            )
        rate = self.options["rate_hz"]
        t = now()
        if rate is None or t >= self._next_at:
            where = f"topic {self.options['topic_name']} ({self.options['topic_type']})"
            self._publisher.publish(self.types.fill(self._types, self.inputs, where))
            if rate is None:
                return _SUCCEEDED
            self._next_at = max(self._next_at + 1.0 / rate, t)
        return _RUNNING

    def on_reset(self) -> None:
        self._next_at = 0.0

    def on_shutdown(self) -> None:
        publisher, self._publisher = self._publisher, None
        if publisher is not None and self._bridge is not None and self._bridge.node is not None:
            self._bridge.node.destroy_publisher(publisher)


class RosSubscribe(RosLeaf):
    """The latest message of a topic to outputs: ``message`` (all of it, as plain data)
    and each of ``fields`` (all top-level fields when null). SUCCEEDED once a message has
    come (and, with ``max_age``, came at most that many seconds ago: a freshness
    condition); FAILED before, saying so."""

    __slots__ = ("_latest", "_seen", "_since", "_subscription", "_types")
    OPTIONS: ClassVar[dict[str, Any]] = {
        **_TOPIC,
        "fields": Port(list[str] | None, None, "fields to outputs; null: all top-level"),
        "max_age": seconds("fail if the latest message is older; null: any age", None),
    }

    def declare_ports(self) -> None:
        port_type = self.types.port_type
        cls = self._types = self.types.interface(self.options["topic_type"], "msg")
        types = self.types.field_types(cls)
        chosen = self.options["fields"]
        if chosen is None:
            chosen = list(types)
        unknown = [f for f in chosen if f not in types]
        if unknown:
            raise RosError(
                f"node {self.name!r}: {self.options['topic_type']} has no field "
                f"{', '.join(map(repr, unknown))}; fields: {', '.join(types)}"
            )
        outs = {"message": Port(dict[str, Any], NO_DEFAULT, "the latest message")}
        for f in chosen:
            outs[f] = Port(port_type(types[f]), NO_DEFAULT, f"field ({types[f]})")
        self.output_ports = normalize_ports(outs, f"{self.name}.outputs")
        self._subscription: Any = None
        self._latest: tuple[Any, float] | None = None
        self._seen: Any = None
        self._since = 0.0

    def on_setup(self) -> None:
        if self._bridge is not None or (self._tree is not None and self._tree.system is not None):
            self._subscribe()

    def _subscribe(self) -> None:
        if self._subscription is None:
            bridge = self.bridge
            name = bridge.resolve(self.options["topic_name"])
            self._subscription = bridge.running().create_subscription(
                self._types, name, self._on_message, qos_of(self, bridge)
            )

    def _on_message(self, message: Any) -> None:  # executor thread
        self._latest = (message, now())

    def _what(self) -> str:
        return f"topic {self.bridge.resolve(self.options['topic_name'])}"

    def _take(self, latest: tuple[Any, float]) -> None:
        message = latest[0]
        if message is self._seen:
            return
        self._seen = message
        plain = self.types.to_plain(message)
        outputs = self.outputs
        outputs["message"] = plain
        for k in outputs:
            if k != "message":
                outputs[k] = plain[k]

    def on_tick(self) -> State:
        self._subscribe()
        latest = self._latest
        if latest is None:
            return self.failed(f"{self._what()}: no message yet")
        age = self.options["max_age"]
        if age is not None and now() - latest[1] > age:
            return self.failed(f"{self._what()}: the latest message is older than {age} s")
        self._take(latest)
        return _SUCCEEDED

    def on_shutdown(self) -> None:
        sub, self._subscription = self._subscription, None
        if sub is not None and self._bridge is not None and self._bridge.node is not None:
            self._bridge.node.destroy_subscription(sub)


class RosWaitForMessage(RosSubscribe):
    """RUNNING until a message arrives after its first tick (since it was halted or reset),
    then SUCCEEDED with it in the outputs; FAILED after ``timeout`` seconds if set."""

    __slots__ = ()
    OPTIONS: ClassVar[dict[str, Any]] = {
        **RosSubscribe.OPTIONS,
        "timeout": seconds("fail after this long without a message; null: wait on", None),
    }

    def on_tick(self) -> State:
        self._subscribe()
        t = now()
        if self.state is not _RUNNING:
            self._since = t
        latest = self._latest
        if latest is not None and latest[1] >= self._since:
            self._take(latest)
            return _SUCCEEDED
        limit = self.options["timeout"]
        if limit is not None and t - self._since > limit:
            return self.failed(f"{self._what()}: no message within timeout {limit} s")
        return _RUNNING
