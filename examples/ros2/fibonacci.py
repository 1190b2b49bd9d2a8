"""Your robot over ROS 2, as a whole program: a behavior tree sends a goal to the robot's
action server and prints the result (docs/ros2.md).

The robot here is a stand-in: a Fibonacci action server (test_msgs, shipped with the
ros-jazzy wheels) started by this program in namespace /husky1. With a real robot, drop
``stand_in_robot`` and point ``action_type``/``action_name`` at its actions
(``nav2_msgs/action/NavigateToPose``, ``navigate_to_pose``).

    make ros && .venv-ros/bin/python examples/ros2/fibonacci.py
"""

from __future__ import annotations

import asyncio
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from btcap import Sequence, Tree
from btcap.ros import RosAction, RosBridge, RosSettings
from btcap.ros.loader import load


@contextmanager
def stand_in_robot(namespace: str) -> Iterator[None]:
    """A ROS 2 node serving test_msgs/action/Fibonacci as NAMESPACE/fibonacci."""
    rclpy = load()
    from rclpy.action import ActionServer
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from test_msgs.action import Fibonacci

    def execute(goal: Any) -> Any:
        seq = [0, 1]
        for _ in range(goal.request.order):
            seq.append(seq[-1] + seq[-2])
            goal.publish_feedback(Fibonacci.Feedback(sequence=seq))
        goal.succeed()
        return Fibonacci.Result(sequence=seq)

    context = Context()
    rclpy.init(context=context)
    node = rclpy.create_node("robot", namespace=namespace, context=context)
    server = ActionServer(node, Fibonacci, "fibonacci", execute_callback=execute)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    thread = threading.Thread(target=executor.spin, daemon=True)
    thread.start()
    try:
        yield
    finally:
        executor.shutdown(timeout_sec=2.0)
        thread.join(timeout=5.0)
        server.destroy()
        node.destroy_node()
        rclpy.shutdown(context=context)


async def main() -> None:
    # The robot's ROS 2 node: domain from ROS_DOMAIN_ID (null), namespace /husky1.
    async with RosBridge(RosSettings(), robot="husky1") as bridge:
        fib = RosAction(
            "fibonacci",
            action_type="test_msgs/action/Fibonacci",
            action_name="fibonacci",  # -> /husky1/fibonacci
            server_timeout=5.0,
            inputs={"order": 8},
            bridge=bridge,
        )
        tree = Tree(Sequence("compute", children=[fib]))
        tree.setup()
        state = await tree.run(rate_hz=50)
        print(f"{state.value}: {fib.outputs['sequence']}")
        await tree.shutdown()


if __name__ == "__main__":
    with stand_in_robot("/husky1"):
        asyncio.run(main())
