"""The simulator behind ROS 2, with real rclpy nodes: a robot's navigation action serves
feedback and a cancel stops the robot; the paper's mission over ROS 2 ends as the direct
simulation does."""

from __future__ import annotations

import threading
import time
from collections import Counter
from collections.abc import Callable
from typing import Any

import anyio
import numpy as np
import pytest
from simserving import serving
from structlog.testing import capture_logs

from btcap.actors import Clock
from btcap.sim.mission.catalog import builtin_scenarios
from btcap.sim.mission.scenario import load_scenario
from btcap.sim.running.runner import run_fast, run_scenario
from btcap.sim.world.manager import SimConfig, SimulationManager
from btcap.sim.world.model import paper_team
from btcap.sim.world.store import MissionState

pytestmark = [pytest.mark.ros, pytest.mark.slow]

#: What a mission's outcome is, in its summary: the same over ROS 2 as directly.
OUTCOME = ("objects", "found", "identified", "contaminated", "decontaminated", "coverage")


def _navigate_then_cancel(
    domain: int, goal_xy: tuple[float, float], after: int, heard: Callable[[], bool]
) -> dict[str, Any]:
    """A plain rclpy client (a thread): once the pose topic's publisher ``heard`` of its
    subscription, send husky1 a navigation goal and cancel it after ``after`` feedback
    messages; what it saw."""
    from btcap.ros.loader import load

    rclpy = load()
    from action_msgs.msg import GoalStatus
    from btcap_sim_msgs.action import NavigateToPose
    from geometry_msgs.msg import PoseStamped
    from rclpy.action import ActionClient
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor

    context = Context()
    rclpy.init(context=context, domain_id=domain)
    node = rclpy.create_node("probe", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    seen: dict[str, Any] = {"feedback": [], "poses": 0}
    try:
        node.create_subscription(
            PoseStamped, "/husky1/pose", lambda _: seen.__setitem__("poses", seen["poses"] + 1), 10
        )
        client = ActionClient(node, NavigateToPose, "/husky1/navigate_to_pose")
        assert client.wait_for_server(timeout_sec=20.0)
        deadline = time.monotonic() + 20.0
        while not heard() and time.monotonic() < deadline:  # discovery: every pose counts
            executor.spin_once(timeout_sec=0.05)
        goal = NavigateToPose.Goal()
        goal.pose.header.frame_id = "map"
        goal.pose.pose.position.x, goal.pose.pose.position.y = goal_xy

        def on_feedback(msg: Any) -> None:
            p = msg.feedback.current_pose.pose.position
            seen["feedback"].append((p.x, p.y))

        sent = client.send_goal_async(goal, feedback_callback=on_feedback)
        executor.spin_until_future_complete(sent, timeout_sec=20.0)
        handle = sent.result()
        seen["accepted"] = handle.accepted
        deadline = time.monotonic() + 20.0
        while min(len(seen["feedback"]), seen["poses"]) < after and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        cancel = handle.cancel_goal_async()
        executor.spin_until_future_complete(cancel, timeout_sec=20.0)
        result = handle.get_result_async()
        executor.spin_until_future_complete(result, timeout_sec=20.0)
        seen["canceled"] = result.result().status == GoalStatus.STATUS_CANCELED
    finally:
        executor.shutdown(timeout_sec=2.0)
        node.destroy_node()
        rclpy.shutdown(context=context)
    return seen


async def test_navigation_feedback_and_a_cancel_that_stops_the_robot(ros_domain: int) -> None:
    from btcap.ros.loader import load

    load()
    s = load_scenario(builtin_scenarios()["full-team"])
    grid = s.grid()
    state = MissionState.scatter(grid, s.objects, s.contaminated_share, np.random.default_rng(1))
    manager = SimulationManager(state, SimConfig(failure_chance=0.0))
    husky = paper_team()["husky"]
    manager.add_robot("husky1", husky)
    # The farthest free cell from the start: a long drive, many cells of feedback.
    free = np.argwhere(grid.free)
    far = free[np.argmax(np.abs(free - np.array(grid.start)).sum(axis=1))]
    goal_xy = (float(far[1]) * grid.cell_size_m, float(far[0]) * grid.cell_size_m)
    clock = Clock(5.0)  # the drive takes about half a minute of wall time: time to cancel
    with anyio.fail_after(120):
        async with serving(
            manager, {"husky1": husky}, grid, clock, domain_id=ros_domain
        ) as servers:
            pub = servers.robots["husky1"].pose_pub
            heard = lambda: pub.get_subscription_count() > 0  # noqa: E731
            seen = await anyio.to_thread.run_sync(
                _navigate_then_cancel, ros_domain, goal_xy, 3, heard
            )
            at = manager.position("husky1")
            await clock.sleep(5.0)  # stopped: it stays where the cancel left it
            assert manager.position("husky1") == at
    assert seen["accepted"]
    assert seen["canceled"]
    assert len(set(seen["feedback"])) >= 3  # a new pose for each cell it drove into
    assert seen["poses"] >= 3
    assert servers.served() == {"husky1": {"navigate_to_pose": 1}}
    assert manager.robots["husky1"].move is None
    assert at not in (grid.start, tuple(far))


async def test_the_full_mission_over_ros2_ends_as_the_direct_simulation(ros_domain: int) -> None:
    direct_s = load_scenario(builtin_scenarios()["full-team"])
    ros_s = load_scenario(builtin_scenarios()["full-team"])  # speed-up 100, wall clock
    threads = {t.name for t in threading.enumerate()}
    with anyio.fail_after(300):
        direct = await run_fast(direct_s)
        with capture_logs() as logs:
            over = await run_scenario(ros_s, ros2=True)
    assert direct.completed, direct.summary
    assert over.completed, over.summary
    assert not over.errors
    assert not over.timed_out
    assert {k: over.summary[k] for k in OUTCOME} == {k: direct.summary[k] for k in OUTCOME}
    assert over.summary["decontaminated"] == over.summary["contaminated"] > 0
    # Every move and operation of every robot came to the simulation through its ROS 2
    # action: the servers took a goal for each (and a move to where a robot already is,
    # which leaves no line on the timeline).
    (served,) = [e["goals"] for e in logs if e["event"] == "sim.ros2_served"]
    assert set(served) == {r.name for r in ros_s.robots}
    for robot, goals in served.items():
        lines = Counter(i.kind for i in over.timeline if i.robot == robot)
        ops = {k: n for k, n in goals.items() if k != "navigate_to_pose"}
        assert ops == {k: n for k, n in lines.items() if k != "move"}, robot
        assert goals.get("navigate_to_pose", 0) >= lines["move"] > 0, robot
    left = {t.name for t in threading.enumerate()} - threads
    assert not {t for t in left if "ros2" in t}, left  # the ROS executor threads are gone
