"""The ROS 2 action server of the ROS benchmark (``bench/ros/ros2.py``), in a process of its own:
``python -m btcap.bench.ros.server NAMESPACE`` serves test_msgs/action/Fibonacci as
``instant`` (succeeds at once, no feedback) and ``stream`` (feedback every millisecond for
``order`` ms, then succeeds) until its standard input closes."""

from __future__ import annotations

import sys
import threading
import time
from typing import Any

from btcap.ros.loader import load


def main(namespace: str) -> None:
    rclpy = load()
    from rclpy.action import ActionServer
    from rclpy.callback_groups import ReentrantCallbackGroup
    from rclpy.context import Context
    from rclpy.executors import MultiThreadedExecutor
    from test_msgs.action import Fibonacci

    context = Context()
    rclpy.init(context=context)
    node = rclpy.create_node("bench_server", namespace=namespace, context=context)
    group = ReentrantCallbackGroup()

    def instant(handle: Any) -> Any:
        handle.succeed()
        return Fibonacci.Result(sequence=[0, 1])

    def stream(handle: Any) -> Any:
        start = time.monotonic()
        for i in range(handle.request.order):
            handle.publish_feedback(Fibonacci.Feedback(sequence=[i]))
            delay = start + (i + 1) * 0.001 - time.monotonic()
            if delay > 0:
                time.sleep(delay)
        handle.succeed()
        return Fibonacci.Result(sequence=[handle.request.order])

    servers = [
        ActionServer(node, Fibonacci, "instant", execute_callback=instant, callback_group=group),
        ActionServer(node, Fibonacci, "stream", execute_callback=stream, callback_group=group),
    ]
    executor = MultiThreadedExecutor(num_threads=2, context=context)
    executor.add_node(node)
    thread = threading.Thread(target=executor.spin, daemon=True)
    thread.start()
    print("ready", flush=True)
    sys.stdin.read()
    executor.shutdown(timeout_sec=2.0)
    thread.join(timeout=5.0)
    for server in servers:
        server.destroy()
    node.destroy_node()
    rclpy.shutdown(context=context)


if __name__ == "__main__":
    main(sys.argv[1])
