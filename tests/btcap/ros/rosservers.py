"""Real ROS 2 servers for the bridge's tests: one rclpy node, on a context and executor
thread of its own (another DDS participant than the bridge's), or in a process of its own
(``python rosservers.py NAMESPACE`` serves until killed; for a server that dies mid-goal).

Fibonacci actions (test_msgs/action/Fibonacci) under the namespace:

- ``fibonacci``: feedback at each of ``order`` steps (2 ms apart), then succeeds;
- ``fibonacci_abort``: aborts; ``fibonacci_reject``: rejects every goal;
- ``fibonacci_hold``: runs until canceled (then CANCELED);
- ``fibonacci_late``: accepts only after ``LATE_S``, then runs until canceled;
- ``fibonacci_stream``: feedback at ~1 kHz for ``order`` ms, then succeeds.

Services (std_srvs/srv/SetBool): ``set_bool`` answers ``success=data``; ``set_bool_slow``
answers after ``SLOW_S``. Topics: ``echo_out`` repeats what comes in on ``echo_in``
(std_msgs/msg/String); given ``pose=(x, y)``, ``pose`` (geometry_msgs/msg/PoseStamped)
at 50 Hz. ``events`` records what the servers saw (accepted, canceled ...).
"""

from __future__ import annotations

import os
import sys
import threading
import time
from collections import Counter
from typing import Any

from btcap.ros.loader import load

__all__ = ["LATE_S", "SLOW_S", "Servers"]

LATE_S = 0.3
SLOW_S = 3.0


class Servers:
    """The test servers of one namespace; ``with Servers(...)`` starts and stops them."""

    def __init__(
        self,
        namespace: str = "/husky1",
        *,
        domain_id: int | None = None,
        pose: tuple[float, float] | None = None,
    ) -> None:
        self.namespace = namespace
        self.pose = pose
        self.domain_id = domain_id
        self.events: Counter[str] = Counter()
        self._stop = threading.Event()

    def __enter__(self) -> Servers:
        rclpy = self.rclpy = load()
        from rclpy.action import ActionServer, CancelResponse, GoalResponse
        from rclpy.callback_groups import ReentrantCallbackGroup
        from rclpy.context import Context
        from rclpy.executors import MultiThreadedExecutor
        from std_msgs.msg import String
        from std_srvs.srv import SetBool
        from test_msgs.action import Fibonacci

        self.context = Context()
        rclpy.init(context=self.context, domain_id=self.domain_id)
        node = self.node = rclpy.create_node(
            "servers", namespace=self.namespace, context=self.context
        )
        group = ReentrantCallbackGroup()
        events = self.events

        def accept(name: str) -> Any:
            def on_goal(request: Any) -> Any:
                if name == "fibonacci_reject":
                    events[f"{name}.rejected"] += 1
                    return GoalResponse.REJECT
                if name == "fibonacci_late":
                    time.sleep(LATE_S)
                events[f"{name}.accepted"] += 1
                return GoalResponse.ACCEPT

            return on_goal

        def on_cancel(request: Any) -> Any:
            events["cancel_requests"] += 1
            return CancelResponse.ACCEPT

        def execute(name: str) -> Any:
            def run(handle: Any) -> Any:
                result = Fibonacci.Result()
                if name == "fibonacci_abort":
                    handle.abort()
                    return result
                seq = [0, 1]
                steps = handle.request.order
                hold = name in ("fibonacci_hold", "fibonacci_late")
                i = 0
                while hold or i < steps:
                    if handle.is_cancel_requested:
                        events[f"{name}.canceled"] += 1
                        handle.canceled()
                        return result
                    if self._stop.is_set():
                        handle.abort()
                        return result
                    seq.append((seq[-1] + seq[-2]) % 1_000_003)  # int32
                    feedback = Fibonacci.Feedback(sequence=seq[-3:])
                    handle.publish_feedback(feedback)
                    i += 1
                    time.sleep(0.001 if name == "fibonacci_stream" else 0.002)
                events[f"{name}.succeeded"] += 1
                handle.succeed()
                result.sequence = seq
                return result

            return run

        self.actions = [
            ActionServer(
                node,
                Fibonacci,
                name,
                execute_callback=execute(name),
                goal_callback=accept(name),
                cancel_callback=on_cancel,
                callback_group=group,
            )
            for name in (
                "fibonacci",
                "fibonacci_abort",
                "fibonacci_reject",
                "fibonacci_hold",
                "fibonacci_late",
                "fibonacci_stream",
            )
        ]

        def set_bool(slow: bool) -> Any:
            def answer(request: Any, response: Any) -> Any:
                if slow:
                    self._stop.wait(SLOW_S)
                response.success = request.data
                response.message = f"data was {request.data}"
                events["set_bool"] += 1
                return response

            return answer

        node.create_service(SetBool, "set_bool", set_bool(False), callback_group=group)
        node.create_service(SetBool, "set_bool_slow", set_bool(True), callback_group=group)
        echo = node.create_publisher(String, "echo_out", 10)
        node.create_subscription(
            String, "echo_in", lambda m: echo.publish(String(data=m.data.upper())), 10
        )
        if self.pose is not None:
            from geometry_msgs.msg import PoseStamped

            where = node.create_publisher(PoseStamped, "pose", 10)
            msg = PoseStamped()
            msg.header.frame_id = "map"
            msg.pose.position.x, msg.pose.position.y = map(float, self.pose)
            self.pose_timer = node.create_timer(0.02, lambda: where.publish(msg))
        self.executor = MultiThreadedExecutor(num_threads=4, context=self.context)
        self.executor.add_node(node)
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()
        return self

    def _spin(self) -> None:
        try:
            self.executor.spin()
        except Exception:
            if not self._stop.is_set():
                raise

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self.executor.shutdown(timeout_sec=3.0)
        self.thread.join(timeout=5.0)
        # rclpy 7 (Jazzy): shutdown() returns without waiting for the callbacks its pool
        # runs; a goal's execute callback still ending (aborted by _stop) would publish its
        # status on a server destroyed below, and the task's "cannot use Destroyable
        # because destruction was requested" was printed at exit as never retrieved.
        pool = getattr(self.executor, "_executor", None)
        if pool is not None:
            pool.shutdown(wait=True)
        # A callback handler that ran on in the pool after shutdown() raised from the
        # executor's destroyed guard condition ("cannot use Destroyable"); its task stays
        # in the executor's list and printed that as "never retrieved" whenever it was
        # collected, into whichever later test read stderr. Read it here.
        with self.executor._tasks_lock:
            tasks = [task for task, _entity, _node in self.executor._tasks]
        for task in tasks:
            if task.done():
                task.exception()
        for server in self.actions:
            server.destroy()
        self.node.destroy_node()
        self.rclpy.shutdown(context=self.context)


if __name__ == "__main__":
    with Servers(sys.argv[1], domain_id=int(os.environ["ROS_DOMAIN_ID"])):
        print("ready", flush=True)
        sys.stdin.read()  # until the test closes stdin or kills us
