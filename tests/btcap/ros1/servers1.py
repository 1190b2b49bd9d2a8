"""Real ROS 1 servers for the bridge's tests, in a rospy process of their own
(``python servers1.py``, with a test master's environment and ``ROS_NAMESPACE``).

- ``count`` (actionlib/Test, SimpleActionServer): goal ``n >= 0``: n feedbacks 0..n-1
  then SUCCEEDED with result 2n; -1: ABORTED; -2: feedback every 20 ms until preempted;
  -3: feedback as fast as it can for 1 s, then SUCCEEDED with the count sent; -4: runs
  forever (the test kills the process); -5: no feedback for 2 s, then SUCCEEDED.
- ``move_base`` (move_base_msgs/MoveBase): three feedbacks at the target, SUCCEEDED.
- ``slow`` (actionlib/Test, ActionServer): accepts a goal 0.5 s after it came, then
  SUCCEEDED with result 7 after 2 s unless canceled (then PREEMPTED; RECALLED, event
  ``slow.recalled``, if canceled before it accepted).
- ``picky`` (actionlib/Test, ActionServer): rejects every goal.
- services ``set_flag`` (std_srvs/SetBool: echoes) and ``stall`` (std_srvs/Trigger:
  answers after 10 s); topic ``chatter_in`` echoed on ``chatter_out`` as ``echo: ...``.

Each event is one line on stdout (``count.succeeded``, ``slow.canceled`` ...); ``up``
once everything is registered. Stdin closing stops the process.
"""

from __future__ import annotations

import sys
import threading
import time

import actionlib
import rospy
from actionlib.msg import TestAction, TestFeedback, TestResult
from move_base_msgs.msg import MoveBaseAction, MoveBaseFeedback
from std_msgs.msg import String
from std_srvs.srv import SetBool, SetBoolResponse, Trigger, TriggerResponse

_out = threading.Lock()


def event(text: str) -> None:
    with _out:
        sys.stdout.write(text + "\n")
        sys.stdout.flush()


def count(server: actionlib.SimpleActionServer, goal: object) -> None:
    n = goal.goal  # type: ignore[attr-defined]
    event(f"count.goal {n}")
    if n == -1:
        server.set_aborted(TestResult(result=-1), "told to abort")
        event("count.aborted")
        return
    if n == -3:
        sent, end = 0, time.monotonic() + 1.0
        while time.monotonic() < end:
            server.publish_feedback(TestFeedback(feedback=sent))
            sent += 1
        server.set_succeeded(TestResult(result=sent))
        event(f"count.flood {sent}")
        return
    if n == -5:
        time.sleep(2.0)
        server.set_succeeded(TestResult(result=5))
        return
    i = 0
    while (n < 0 or i < n) and not rospy.is_shutdown():  # a goal nobody cancels ends too
        if server.is_preempt_requested():
            server.set_preempted(TestResult(result=i))
            event("count.preempted")
            return
        server.publish_feedback(TestFeedback(feedback=i))
        i += 1
        time.sleep(0.02)
    server.set_succeeded(TestResult(result=2 * n))
    event("count.succeeded")


def move_base(server: actionlib.SimpleActionServer, goal: object) -> None:
    for _ in range(3):
        server.publish_feedback(MoveBaseFeedback(base_position=goal.target_pose))  # type: ignore[attr-defined]
        time.sleep(0.02)
    server.set_succeeded()
    event("move_base.succeeded")


class Slow:
    """Accepts late; canceled goals end PREEMPTED (or RECALLED before acceptance)."""

    def __init__(self) -> None:
        self.server = actionlib.ActionServer(
            "slow", TestAction, self.on_goal, self.on_cancel, False
        )
        self.canceled: set[str] = set()

    def on_goal(self, handle: actionlib.ServerGoalHandle) -> None:
        event("slow.goal")
        threading.Thread(target=self.run, args=(handle,), daemon=True).start()

    def run(self, handle: actionlib.ServerGoalHandle) -> None:
        time.sleep(0.5)
        gid = handle.get_goal_id().id
        if gid in self.canceled:
            return  # recalled already, in on_cancel
        handle.set_accepted()
        event("slow.accepted")
        end = time.monotonic() + 2.0
        while time.monotonic() < end:
            if gid in self.canceled:
                handle.set_canceled(TestResult(result=-7))
                event("slow.canceled")
                return
            handle.publish_feedback(TestFeedback(feedback=1))
            time.sleep(0.02)
        handle.set_succeeded(TestResult(result=7))
        event("slow.succeeded")

    def on_cancel(self, handle: actionlib.ServerGoalHandle) -> None:
        gid = handle.get_goal_id().id
        self.canceled.add(gid)
        # PENDING, or RECALLING (actionlib's own move on a cancel of a pending goal,
        # made before it calls this): recall it now
        if handle.get_goal_status().status in (0, 7):
            handle.set_canceled(TestResult(result=-7))
            event("slow.recalled")


def main() -> None:
    rospy.init_node("servers", disable_signals=True)
    servers = []
    simple = actionlib.SimpleActionServer
    c = simple("count", TestAction, execute_cb=lambda g: count(c, g), auto_start=False)
    m = simple("move_base", MoveBaseAction, execute_cb=lambda g: move_base(m, g), auto_start=False)
    slow = Slow()
    picky = actionlib.ActionServer(
        "picky",
        TestAction,
        lambda h: (h.set_rejected(TestResult(), "no"), event("picky.rejected")),
        lambda h: None,
        False,
    )
    servers = [c, m, slow.server, picky]
    for s in servers:
        s.start()

    def set_flag(request: object) -> SetBoolResponse:
        event("set_flag.called")
        return SetBoolResponse(success=request.data, message=f"flag {request.data}")  # type: ignore[attr-defined]

    def stall(request: object) -> TriggerResponse:
        event("stall.called")
        time.sleep(10.0)
        return TriggerResponse(success=True, message="late")

    rospy.Service("set_flag", SetBool, set_flag)
    rospy.Service("stall", Trigger, stall)
    echo = rospy.Publisher("chatter_out", String, queue_size=10)
    rospy.Subscriber("chatter_in", String, lambda msg: echo.publish(String(f"echo: {msg.data}")))
    event("up")
    sys.stdin.read()  # until the test closes it
    rospy.signal_shutdown("test over")


if __name__ == "__main__":
    main()
