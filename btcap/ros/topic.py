"""Topic nodes: RosPublish (once, or at a rate), RosSubscribe (the latest message, or
chosen fields, to outputs; optionally only if fresh) and RosWaitForMessage (running until
a new message arrives).

Port names follow BehaviorTree.ROS2 (``topic_name``, an input: a literal or a blackboard
entry); QoS is the robot's default unless the node sets ``reliability``, ``durability``
or ``depth``. Messages arrive on the bridge's executor thread, which keeps the latest and
when it came, and ticks the tree soon when a RosWaitForMessage waits for one.

``topic_name`` is read when the node starts (a publish, a run at a rate, a wait; each
tick of a RosSubscribe): a new name replaces the publisher or subscription, and a
subscriber then has no message of the new topic yet.
"""

from __future__ import annotations

from typing import Any, ClassVar

from msgspec import Meta

from btcap.bt.ports import NO_DEFAULT, Port, normalize_ports
from btcap.bt.state import State
from btcap.ros.base import QOS_OPTIONS, RosLeaf, name_input, now, qos_of, seconds
from btcap.ros.errors import RosError

__all__ = ["RosPublish", "RosSubscribe", "RosWaitForMessage"]

_RUNNING = State.RUNNING
_SUCCEEDED = State.SUCCEEDED
_FAILED = State.FAILED

_TOPIC: dict[str, Any] = {
    "topic_type": Port(str, description="e.g. `geometry_msgs/msg/PoseStamped`"),
    **QOS_OPTIONS,
}


def _drop(node: RosLeaf, what: Any, destroy: str) -> None:
    """Destroy a publisher or subscription of ``node``'s bridge, if it still runs."""
    bridge = node._bridge
    if what is not None and bridge is not None and bridge.node is not None:
        getattr(bridge.node, destroy)(what)


_NAME = name_input("topic_name", "topic")


class RosPublish(RosLeaf):
    """Publishes a message made of its inputs: once (SUCCEEDED), or every ``1/rate_hz``
    seconds while ticked (RUNNING until halted). A subscriber of another type on the topic
    is told once (ROS 2: a :class:`~btcap.ros.errors.RosTypeWarning`); it does not fail
    the node, which reaches the subscribers of its own type."""

    __slots__ = ("_next_at", "_publisher", "_topic", "_types")
    INPUTS: ClassVar[dict[str, Any]] = _NAME
    OPTIONS: ClassVar[dict[str, Any]] = {
        **_TOPIC,
        "rate_hz": Port(float | None, None, "publish at this rate; null: once", Meta(gt=0)),
    }

    def declare_ports(self) -> None:
        cls = self._types = self.types.interface(self.options["topic_type"], "msg")
        fields = {
            k: Port(self.types.port_type(t) | None, None, f"message field ({t})")
            for k, t in self.types.field_types(cls).items()
        }
        self.input_ports = normalize_ports(
            self.with_name_port(fields, self.options["topic_type"]), f"{self.name}.inputs"
        )
        self._publisher: Any = None
        self._topic = ""
        self._next_at = 0.0

    def on_tick(self) -> State:
        bridge = self.bridge
        if self._publisher is None or self.state is not _RUNNING:
            name = self.ros_name()
            if name != self._topic:
                _drop(self, self._publisher, "destroy_publisher")
                self._publisher = None
                self._publisher = bridge.running().create_publisher(
                    self._types, name, qos_of(self, bridge)
                )
                self._topic = name
        self.peer_type(self._publisher)  # told once if a subscriber has another type
        rate = self.options["rate_hz"]
        t = now()
        if rate is None or t >= self._next_at:
            where = f"topic {self._topic} ({self.options['topic_type']})"
            fields = {k: v for k, v in self.inputs.items() if k != "topic_name"}
            self._publisher.publish(self.types.fill(self._types, fields, where))
            if rate is None:
                return _SUCCEEDED
            self._next_at = max(self._next_at + 1.0 / rate, t)
        return _RUNNING

    def on_reset(self) -> None:
        self._next_at = 0.0

    def on_shutdown(self) -> None:
        publisher, self._publisher = self._publisher, None
        self._topic = ""
        _drop(self, publisher, "destroy_publisher")


class RosSubscribe(RosLeaf):
    """The latest message of a topic to outputs: ``message`` (all of it, as plain data)
    and each of ``fields`` (all top-level fields when null). SUCCEEDED once a message has
    come (and, with ``max_age``, came at most that many seconds ago: a freshness
    condition); FAILED before, saying so."""

    __slots__ = (
        "_incompatible",
        "_latest",
        "_seen",
        "_since",
        "_subscription",
        "_topic",
        "_types",
        "_waits",
    )
    INPUTS: ClassVar[dict[str, Any]] = _NAME
    OPTIONS: ClassVar[dict[str, Any]] = {
        **_TOPIC,
        "fields": Port(list[str] | None, None, "fields to outputs; null: all top-level"),
        "max_age": seconds("fail if the latest message is older; null: any age", None),
    }

    def declare_ports(self) -> None:
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
        self.input_ports = normalize_ports(self.name_port(), f"{self.name}.inputs")
        outs = {"message": Port(dict[str, Any], NO_DEFAULT, "the latest message")}
        for f in chosen:
            outs[f] = Port(self.types.port_type(types[f]), NO_DEFAULT, f"field ({types[f]})")
        self.output_ports = normalize_ports(outs, f"{self.name}.outputs")
        self._subscription: Any = None
        self._topic = ""
        self._latest: tuple[Any, float] | None = None
        self._seen: Any = None
        self._since = 0.0
        self._waits: Any = None  # RosWaitForMessage: news(), while it waits
        self._incompatible: str | None = None  # a QoS policy a publisher disagrees on

    def on_setup(self) -> None:
        """Subscribe now, so the first tick may have a message, when the name is known
        (a literal) and there is a bridge; else at the first tick."""
        known = self._bridge is not None or (
            self._tree is not None and self._tree.system is not None
        )
        if known and self.literal_name() is not None:
            self._subscribe()

    def _subscribe(self) -> None:
        name = self.ros_name()
        if self._subscription is None or name != self._topic:
            bridge = self.bridge
            _drop(self, self._subscription, "destroy_subscription")
            self._subscription = None
            self._latest = None
            self._incompatible = None
            self._subscription = bridge.running().create_subscription(
                self._types,
                name,
                self._on_message,
                qos_of(self, bridge),
                **bridge.subscription_events(name, self._on_incompatible),
            )
            self._topic = name

    def _on_message(self, message: Any) -> None:  # executor thread
        self._latest = (message, now())
        news = self._waits
        if news is not None:
            news(False)

    def _on_incompatible(self, policy: str) -> None:  # executor thread
        self._incompatible = policy

    def _what(self) -> str:
        return f"topic {self._topic}"

    def _none(self, why: str) -> State:
        """FAILED for want of a message: ``why``, and a publisher of another type or
        whose QoS this node does not accept, if one was seen (else the error says only
        "no message yet")."""
        found = self.peer_type(self._subscription)
        if found is not None:
            why += f": type mismatch: expected {self.options['topic_type']}, found {found}"
        policy = self._incompatible
        if policy is not None:
            why += (
                f": a publisher of it offers a QoS this node does not accept ({policy}), so "
                "none of its messages arrive; set the node's reliability, durability or "
                "depth to match"
            )
        return self.failed(f"{self._what()}: {why}")

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
            return self._none("no message yet")
        age = self.options["max_age"]
        if age is not None and now() - latest[1] > age:
            return self.failed(f"{self._what()}: the latest message is older than {age} s")
        self._take(latest)
        return _SUCCEEDED

    def on_shutdown(self) -> None:
        sub, self._subscription = self._subscription, None
        self._topic = ""
        self._waits = None
        _drop(self, sub, "destroy_subscription")


class RosWaitForMessage(RosSubscribe):
    """RUNNING until a message arrives after its first tick (since it was halted or reset),
    then SUCCEEDED with it in the outputs; FAILED after ``timeout`` seconds if set, and as
    soon as the topic is seen published with another type only."""

    __slots__ = ()
    OPTIONS: ClassVar[dict[str, Any]] = {
        **RosSubscribe.OPTIONS,
        "timeout": seconds("fail after this long without a message; null: wait on", None),
    }

    def on_tick(self) -> State:
        t = now()
        if self.state is not _RUNNING or self._subscription is None:
            self._subscribe()  # the name, read when the wait starts
            self._since = t
            self._waits = self.news()
        latest = self._latest
        if latest is not None and latest[1] >= self._since:
            self._waits = None
            self._take(latest)
            return _SUCCEEDED
        if self.peer_type(self._subscription) is not None:  # none of its would come
            self._waits = None
            return self._none("no message")
        limit = self.options["timeout"]
        if limit is not None and t - self._since > limit:
            self._waits = None
            return self._none(f"no message within timeout {limit} s")
        return _RUNNING

    def on_untick(self) -> None:
        self._waits = None

    def on_reset(self) -> None:
        self._waits = None
