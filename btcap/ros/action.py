"""RosAction: a ROS 2 action goal as a tree node, BehaviorTree.ROS2's RosActionNode in
btcap's terms.

Inputs are the Goal's fields, typed from the interface (as ros_bt_py does); outputs are
the Result's fields and, prefixed ``feedback_``, the latest Feedback's, copied at each
tick while the goal runs. The node never waits: the goal is sent with rclpy's
``send_goal_async`` and the answers arrive on the bridge's executor thread, which only
records them in the goal's :class:`_Goal`; the tick reads them. Halting cancels the goal,
also when the server has not accepted it yet (the answer, when it comes, is cancelled
then: the race BehaviorTree.ROS2 #18/#53 and Nav2 #6426 report); halting twice does
nothing more. Every way to fail says why in ``node.error``; no timeout is a success.
``result_timeout`` bounds a goal's whole run (a server that accepts it and never ends
it would hold the node RUNNING for ever): past it the goal is cancelled and the node
fails.

The news (accepted, rejected, feedback, result) ticks the node's tree soon
(:meth:`~btcap.ros.base.RosLeaf.news`). ``action_name`` is read when a goal is sent: a
goal runs to its end on the server it was sent to, whatever the name becomes meanwhile.
"""

from __future__ import annotations

import threading
from typing import Any, ClassVar

from btcap.bt.ports import NO_DEFAULT, Port, normalize_ports
from btcap.bt.state import State
from btcap.ros.base import SERVER_OPTIONS, RosLeaf, name_input, now, seconds
from btcap.ros.versions import Types

__all__ = ["FEEDBACK_PREFIX", "RosAction"]

_RUNNING = State.RUNNING
_SUCCEEDED = State.SUCCEEDED

#: action_msgs/GoalStatus codes of a goal's end, by name; ROS 1's are 100 + actionlib's
#: (btcap.ros.facade1.end_code; its SUCCEEDED is 4).
_ENDS = {4: "succeeded", 5: "canceled", 6: "aborted", 102: "preempted", 104: "aborted"}
_ENDS |= {108: "recalled", 109: "lost"}
_REJECTED = -1

FEEDBACK_PREFIX = "feedback_"


def _quiet(minor: bool = False) -> None:
    """A halted goal's news: none."""


class _Goal:
    """One goal's answers, written by the executor thread, read by the tick.

    The bridge tracks it from its sending until it is over for the server: ended,
    rejected, failed, or its cancel answered (:meth:`RosBridge.track
    <btcap.ros.client.RosBridge.track>`), so closing the bridge cancels it even before the
    server accepted it. A halted goal's answers tell the tree nothing any more."""

    __slots__ = (
        "bridge",
        "client",
        "error",
        "feedback",
        "feedback_at",
        "feedback_seen",
        "halted",
        "halted_at",
        "handle",
        "key",
        "lock",
        "name",
        "news",
        "result",
        "sent_at",
        "status",
    )

    def __init__(self, bridge: Any, client: Any, name: str, news: Any) -> None:
        self.bridge = bridge
        self.client = client
        self.name = name
        self.news = news
        self.lock = threading.Lock()
        self.handle: Any = None
        self.key: Any = None
        self.halted = False
        self.halted_at = 0.0
        self.status: int | None = None
        self.result: Any = None
        self.error: str | None = None
        self.feedback: Any = None
        self.feedback_at = 0.0
        self.feedback_seen: Any = None
        self.sent_at = now()

    # tick thread
    def send(self, message: Any) -> None:
        future, self.key = self.bridge.send_goal(self.client, message, self.on_feedback)
        self.bridge.track(self)
        future.add_done_callback(self.on_response)

    def halt(self) -> None:
        """Cancel the goal (now if accepted, else as soon as it is); once."""
        with self.lock:
            if self.halted:
                return
            self.halted = True
            self.halted_at = now()
            handle = self.handle
            # Nothing of it is news any more; the client may keep this goal's callbacks
            # for good (its server died: no result ever comes), so they must not hold
            # the node's tree.
            self.news = _quiet
        if self.bridge.halt_goal(self.key):  # ROS 1: cancelled now, and forgotten
            self.bridge.untrack(self)
        elif handle is not None and self.status is None:
            self._cancel(handle)

    # executor thread
    def on_response(self, future: Any) -> None:
        try:
            handle = future.result()
        except Exception as exc:
            self.error = f"the goal request failed: {exc}"
            self._over()
            return
        if handle is None or not handle.accepted:
            self.status = _REJECTED
            self._over()
            return
        with self.lock:
            self.handle = handle
            self.feedback_at = now()
            cancel = self.halted
        # Also for a goal halted before: its result is how it ends for rclpy's client,
        # which keeps the goal's feedback callback (and so this node) until then.
        handle.get_result_async().add_done_callback(self.on_result)
        if cancel:  # halted before the server accepted: cancel it now
            self._cancel(handle)
        else:
            self.news()

    def on_result(self, future: Any) -> None:
        try:
            answer = future.result()
        except Exception as exc:
            self.error = f"the result request failed: {exc}"
        else:
            self.result = answer.result
            self.status = answer.status
        self._over()

    def on_feedback(self, message: Any) -> None:
        self.feedback = message.feedback
        self.feedback_at = now()
        self.news(True)

    # either thread
    def _cancel(self, handle: Any) -> None:
        future = handle.cancel_goal_async()
        if future is None:  # ROS 1: its process answers for it
            self.bridge.untrack(self)
        else:
            future.add_done_callback(lambda _: self.bridge.untrack(self))

    def _over(self) -> None:
        """Nothing more comes from the server: drop the goal from the bridge and what the
        client keeps of it; tell the tree, unless halted."""
        self.bridge.forget_goal(self.client, self.key)
        self.bridge.untrack(self)
        if not self.halted:
            self.news()


class RosAction(RosLeaf):
    """Sends a goal to a ROS 2 action server and runs until its result.

    SUCCEEDED when the goal succeeds (the Result's fields in the outputs); FAILED, with
    the reason in ``error``, when it is aborted, canceled by the server or rejected, when
    no server appears within ``wait_for_server_timeout`` or answers the goal within
    ``server_timeout`` (seconds), when ``feedback_timeout`` passes without feedback, when
    the goal has no result ``result_timeout`` after it was sent (it is cancelled), when
    the server leaves the graph mid-goal, or, as soon as it is seen, when only a server
    of another type serves the action (also told once as a
    :class:`~btcap.ros.errors.RosTypeWarning`).
    """

    __slots__ = ("_goal", "_last", "_types")
    KIND: ClassVar[str] = "action"
    NAME_PORT: ClassVar[str] = "action_name"
    INPUTS: ClassVar[dict[str, Any]] = name_input("action_name", "action")
    OPTIONS: ClassVar[dict[str, Any]] = {
        "action_type": Port(str, description="e.g. `nav2_msgs/action/NavigateToPose`"),
        **SERVER_OPTIONS,
        "feedback_timeout": seconds("fail after this long without feedback; null: never", None),
        "result_timeout": seconds(
            "cancel the goal and fail if it has no result this long after it was sent; "
            "null: wait as long as the server runs it",
            None,
        ),
    }

    def declare_ports(self) -> None:
        cls = self.types.interface(self.options["action_type"], "action")
        self._types = cls
        goal = self.types.field_types(cls.Goal)
        fields = {
            k: Port(self.types.port_type(t) | None, None, f"Goal field ({t})")
            for k, t in goal.items()
        }
        self.input_ports = normalize_ports(
            self.with_name_port(fields, f"{self.options['action_type']} Goal"),
            f"{self.name}.inputs",
        )
        outs = {
            k: Port(self.types.port_type(t), NO_DEFAULT, f"Result ({t})")
            for k, t in _fields(self.types, cls.Result)
        }
        for k, t in _fields(self.types, cls.Feedback):
            outs[FEEDBACK_PREFIX + k] = Port(
                self.types.port_type(t), NO_DEFAULT, f"latest Feedback ({t})"
            )
        self.output_ports = normalize_ports(outs, f"{self.name}.outputs")
        self._goal: _Goal | None = None
        self._last = ""

    @property
    def action_name(self) -> str:
        """The action's name, resolved: the running goal's, else the input's now."""
        return self._goal.name if self._goal is not None else self.ros_name()

    def _what(self) -> str:
        name = self._goal.name if self._goal is not None else self._last or "?"
        return f"action {name} ({self.options['action_type']})"

    def on_tick(self) -> State:
        goal = self._goal
        if goal is None:
            return self._send()
        fb = goal.feedback
        if fb is not None and fb is not goal.feedback_seen:
            goal.feedback_seen = fb
            outputs = self.outputs
            for k, v in self.types.to_plain(fb).items():
                outputs[FEEDBACK_PREFIX + k] = v
        if goal.status is not None:
            return self._finish(goal)
        if goal.error is not None:
            self._goal = None
            return self.failed(f"{self._what()}: {goal.error}")
        t = now()
        overall = self.options["result_timeout"]
        if overall is not None and t - goal.sent_at > overall:
            self._stop()  # cancels it, also if the server has not accepted it yet
            return self.failed(
                f"{self._what()}: no result within result_timeout {overall} s; the goal "
                "was cancelled"
            )
        if goal.handle is None:
            if t - goal.sent_at > self.options["server_timeout"]:
                self._stop()
                return self.failed(
                    f"{self._what()}: no answer to the goal within server_timeout "
                    f"{self.options['server_timeout']} s"
                )
            return _RUNNING
        limit = self.options["feedback_timeout"]
        if limit is not None and t - goal.feedback_at > limit:
            self._stop()
            return self.failed(f"{self._what()}: no feedback for feedback_timeout {limit} s")
        if not goal.client.server_is_ready():
            self._stop()
            return self.failed(f"{self._what()}: the server left during the goal")
        return _RUNNING

    def _send(self) -> State:
        bridge = self.bridge
        name = self._last = self.ros_name()
        kind = self.options["action_type"]
        client = bridge.action_client(kind, name)
        ready = client.server_is_ready()
        if not ready and (wrong := self.mismatched(client, f"action {name}", kind)) is not None:
            return wrong
        if (missing := self._server_missing(ready, name)) is not None:
            return missing
        fields = {k: v for k, v in self.inputs.items() if k != "action_name"}
        msg = self.types.fill(self._types.Goal, fields, f"{self._what()} goal")
        goal = self._goal = _Goal(bridge, client, name, self.news())
        outputs = self.outputs
        for k in outputs:
            outputs[k] = None
        goal.send(msg)
        return _RUNNING

    def _finish(self, goal: _Goal) -> State:
        self._goal = None
        status = goal.status
        if status == 4:
            outputs = self.outputs
            for k, v in self.types.to_plain(goal.result).items():
                outputs[k] = v
            return _SUCCEEDED
        if status == _REJECTED:
            return self.failed(f"{self._what()}: the goal was rejected by the server")
        end = _ENDS.get(status or 0, f"ended with status {status}")
        return self.failed(f"{self._what()}: the goal was {end}")

    def _stop(self) -> None:
        goal, self._goal = self._goal, None
        self._waiting_since = None
        if goal is not None:
            goal.halt()

    def on_untick(self) -> None:
        self._stop()

    def on_reset(self) -> None:
        self._stop()

    def on_shutdown(self) -> None:
        self._stop()


def _fields(types: Types, cls: Any) -> list[tuple[str, str]]:
    return list(types.field_types(cls).items())
