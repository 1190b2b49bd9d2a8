"""The ROS 1 bridge's clients, shaped like the rclpy objects the tree nodes use (an action
client's ``send_goal_async`` and goal handles, a service client's ``call_async``, a node's
publishers and subscriptions), so :class:`~btcap.ros.action.RosAction` and its siblings
run unchanged over either ROS version.

Each one stands for a client in the robot's rospy process (:mod:`btcap.ros.child1`) and
sends it frames; the bridge's reader thread completes their futures and hands them
messages, as rclpy's executor thread does for ROS 2. Readiness is what the rospy process
last reported, so asking costs nothing.
"""

from __future__ import annotations

import io
import threading
from collections.abc import Callable
from typing import Any, Protocol

from btcap.ros import wire1
from btcap.ros.errors import RosError

__all__ = [
    "ActionClient1",
    "Future1",
    "GoalHandle1",
    "Node1",
    "Publisher1",
    "ServiceClient1",
    "Subscription1",
    "end_code",
    "serialize",
]

#: actionlib_msgs/GoalStatus codes.
PREEMPTED, SUCCEEDED, REJECTED, RECALLED = 2, 3, 5, 8


class Ros1Bridge(Protocol):
    """What these clients ask of :class:`btcap.ros.client1.Ros1Bridge`."""

    def next_id(self) -> int: ...
    def send(self, frame: wire1.Down) -> None: ...
    def open(self, kind: str, type_name: str, name: str, qos: tuple[int, bool]) -> int: ...
    def drop(self, cid: int) -> None: ...
    def open_goal(self, handle: GoalHandle1) -> None: ...
    def call(self, client: ServiceClient1, data: bytes) -> Future1: ...
    def forget_call(self, future: Future1) -> None: ...
    def subscribe(
        self, sub: Subscription1, type_name: str, name: str, qos: tuple[int, bool]
    ) -> None: ...


def end_code(status: int) -> int:
    """A ROS 1 goal's end as the code RosAction reads: SUCCEEDED is action_msgs' 4; the
    others are 100 + their actionlib_msgs/GoalStatus code (``preempted`` is 102)."""
    return 4 if status == SUCCEEDED else 100 + status


def serialize(message: Any) -> bytes:
    buf = io.BytesIO()
    message.serialize(buf)
    return buf.getvalue()


class Future1:
    """rclpy's Future as far as the nodes use it; done from the bridge's reader thread."""

    __slots__ = ("_callbacks", "_done", "_exception", "_lock", "_result")

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._done = False
        self._result: Any = None
        self._exception: BaseException | None = None
        self._callbacks: list[Callable[[Future1], None]] = []

    def done(self) -> bool:
        return self._done

    def result(self) -> Any:
        if self._exception is not None:
            raise self._exception
        return self._result

    def exception(self) -> BaseException | None:
        return self._exception

    def add_done_callback(self, callback: Callable[[Future1], None]) -> None:
        with self._lock:
            if not self._done:
                self._callbacks.append(callback)
                return
        callback(self)

    def set(self, result: Any = None, exception: BaseException | None = None) -> None:
        with self._lock:
            if self._done:
                return
            self._result, self._exception, self._done = result, exception, True
            callbacks, self._callbacks = self._callbacks, []
        for callback in callbacks:
            callback(self)


class _Answer:
    """A goal's end, as rclpy's GetResult response: ``status`` and ``result``."""

    __slots__ = ("result", "status", "text")

    def __init__(self, status: int, result: Any, text: str) -> None:
        self.status, self.result, self.text = status, result, text


class _FeedbackMessage:
    __slots__ = ("feedback",)

    def __init__(self, feedback: Any) -> None:
        self.feedback = feedback


class GoalHandle1:
    """One goal: ``accepted``, ``cancel_goal_async`` and ``get_result_async``."""

    __slots__ = ("accepted", "bridge", "client", "ended", "feedback_callback", "gid", "response")

    def __init__(self, client: ActionClient1, gid: int, feedback_callback: Any) -> None:
        self.client = client
        self.bridge = client.bridge
        self.gid = gid
        self.accepted = False
        self.feedback_callback = feedback_callback
        self.response = Future1()  # -> this handle, once accepted or rejected
        self.ended = Future1()  # -> _Answer

    def cancel_goal_async(self) -> None:
        self.bridge.send(wire1.Cancel(self.gid))

    def get_result_async(self) -> Future1:
        return self.ended

    # the bridge's reader thread
    def on_accepted(self) -> None:
        self.accepted = True
        self.response.set(self)

    def on_feedback(self, data: bytes) -> None:
        if self.feedback_callback is not None:
            message = self.client.types.Feedback().deserialize(data)
            self.feedback_callback(_FeedbackMessage(message))

    def on_done(self, frame: wire1.Done) -> None:
        if not self.response.done():  # ended before its acceptance was seen
            if frame.status in (REJECTED, RECALLED):
                self.response.set(self)  # not accepted: RosAction says "rejected"
                return
            self.on_accepted()
        result = self.client.types.Result()
        if frame.data:
            result.deserialize(frame.data)
        self.ended.set(_Answer(end_code(frame.status), result, frame.text))

    def on_lost(self, why: str) -> None:
        error = RosError(why)
        self.response.set(exception=error)
        self.ended.set(exception=error)


class ActionClient1:
    """An actionlib ActionClient in the rospy process. ``mismatch``: the type its server
    has, when another than its own (None: none seen)."""

    __slots__ = ("bridge", "cid", "mismatch", "ready", "types")

    def __init__(self, bridge: Ros1Bridge, cid: int, types: Any) -> None:
        self.bridge, self.cid, self.types = bridge, cid, types
        self.ready = False
        self.mismatch: str | None = None

    def server_is_ready(self) -> bool:
        return self.ready

    def send_goal_async(self, goal: Any, feedback_callback: Any = None) -> Future1:
        return self.send_goal(goal, feedback_callback).response

    def send_goal(self, goal: Any, feedback_callback: Any = None) -> GoalHandle1:
        """Send ``goal``: its handle, whose ``response`` is done once it is accepted."""
        handle = GoalHandle1(self, self.bridge.next_id(), feedback_callback)
        self.bridge.open_goal(handle)
        self.bridge.send(wire1.Goal(self.cid, handle.gid, serialize(goal)))
        return handle

    def destroy(self) -> None:
        self.bridge.drop(self.cid)


class ServiceClient1:
    """A rospy ServiceProxy in the rospy process; ``mismatch`` as an action client's."""

    __slots__ = ("bridge", "cid", "mismatch", "ready", "types")

    def __init__(self, bridge: Ros1Bridge, cid: int, types: Any) -> None:
        self.bridge, self.cid, self.types = bridge, cid, types
        self.ready = False
        self.mismatch: str | None = None

    def service_is_ready(self) -> bool:
        return self.ready

    def call_async(self, request: Any) -> Future1:
        return self.bridge.call(self, serialize(request))

    def remove_pending_request(self, future: Future1) -> None:
        self.bridge.forget_call(future)


class Publisher1:
    __slots__ = ("bridge", "cid")

    def __init__(self, bridge: Ros1Bridge, cid: int) -> None:
        self.bridge, self.cid = bridge, cid

    def publish(self, message: Any) -> None:
        self.bridge.send(wire1.Publish(self.cid, serialize(message)))


class Subscription1:
    """A rospy Subscriber in the rospy process; ``mismatch``: the type its topic is
    published with, when another than its own and no publisher of its own type is there."""

    __slots__ = ("bridge", "callback", "cid", "mismatch", "types")

    def __init__(self, bridge: Ros1Bridge, cid: int, types: Any, callback: Any) -> None:
        self.bridge, self.cid, self.types, self.callback = bridge, cid, types, callback
        self.mismatch: str | None = None

    def on_message(self, data: bytes) -> None:  # the bridge's reader thread
        self.callback(self.types().deserialize(data))


class Node1:
    """The robot's node as the topic nodes use it (``bridge.running()``, ``bridge.node``).
    ``qos`` is :meth:`Ros1Bridge.qos`'s ``(queue size, latch)``."""

    __slots__ = ("bridge",)

    def __init__(self, bridge: Ros1Bridge) -> None:
        self.bridge = bridge

    def create_publisher(self, types: Any, name: str, qos: tuple[int, bool]) -> Publisher1:
        cid = self.bridge.open("publisher", types._type, name, qos)
        return Publisher1(self.bridge, cid)

    def create_subscription(
        self, types: Any, name: str, callback: Any, qos: tuple[int, bool]
    ) -> Subscription1:
        cid = self.bridge.next_id()
        sub = Subscription1(self.bridge, cid, types, callback)
        self.bridge.subscribe(sub, types._type, name, qos)
        return sub

    def destroy_publisher(self, publisher: Publisher1) -> None:
        self.bridge.drop(publisher.cid)

    def destroy_subscription(self, subscription: Subscription1) -> None:
        self.bridge.drop(subscription.cid)
