"""News from ROS ticks the node's tree soon: a tree run at 1 Hz on a clock that never
moves (nothing but the news can tick it) still gets its goal's result, its service's
response and an awaited message; a 1 kHz feedback stream does not tick it 1000 times a
second."""

from __future__ import annotations

import asyncio
import time

import anyio
import pytest
from rosservers import Servers
from rostools import FOUND_S, wait_for

from btcap.actors import ManualClock
from btcap.bt.composites import Sequence
from btcap.bt.node import Node
from btcap.bt.state import DONE, State
from btcap.bt.tree import Tree
from btcap.ros.action import RosAction
from btcap.ros.client import RosBridge
from btcap.ros.service import RosService
from btcap.ros.topic import RosWaitForMessage
from btcap.ros.waker import FEEDBACK_WAKE_S, Waker
from btcap.team.capabilities.capability import CapabilityInterface
from btcap.team.capabilities.implementation import Implementation
from btcap.team.core.hosting import Hosted
from btcap.team.ids import ExecutionId
from btcap.team.runtime.agent import Agent

pytestmark = pytest.mark.ros

FIB = "test_msgs/action/Fibonacci"


class Ticks:
    def __init__(self) -> None:
        self.n = 0

    def __call__(self, state: State) -> bool:
        self.n += 1
        return state is not State.RUNNING


async def run_frozen(root: Node) -> tuple[State, int]:
    """Run ``root``'s tree at 1 Hz on a clock that stays at 0: only news ticks it."""
    clock = ManualClock()
    tree = Tree(root, clock=clock)
    ticks = Ticks()
    state = await tree.run(rate_hz=1.0, until=ticks)
    assert clock.now() == 0.0
    await tree.shutdown()
    return state, ticks.n


async def test_goal_answers_response_and_message_tick_the_tree(
    ros_domain: int, bridge: RosBridge
) -> None:
    with Servers("/husky1", domain_id=ros_domain, pose=(1.0, 2.0)) as servers:
        with anyio.fail_after(20):
            await wait_for(lambda: bridge.server_ready("action", FIB, "fibonacci"))
            await wait_for(
                lambda: bridge.server_ready("service", "std_srvs/srv/SetBool", "set_bool")
            )
            root = Sequence(
                "seq",
                children=[
                    RosAction(
                        "fib",
                        action_type=FIB,
                        action_name="fibonacci",
                        bridge=bridge,
                        server_timeout=FOUND_S,
                        inputs={"order": 3},
                    ),
                    RosService(
                        "call",
                        service_type="std_srvs/srv/SetBool",
                        service_name="set_bool",
                        bridge=bridge,
                        server_timeout=FOUND_S,
                        inputs={"data": True},
                    ),
                    RosWaitForMessage(
                        "pose",
                        topic_type="geometry_msgs/msg/PoseStamped",
                        topic_name="pose",
                        bridge=bridge,
                    ),
                ],
            )
            state, _ = await run_frozen(root)
    assert state is State.SUCCEEDED, [n.error for n in root.walk() if n.error]
    assert servers.events["fibonacci.succeeded"] == 1
    assert root.children[2].outputs["pose"]["position"]["x"] == 1.0


async def test_a_1khz_feedback_stream_ticks_the_tree_at_most_every_feedback_wake_s(
    servers: Servers, bridge: RosBridge
) -> None:
    with anyio.fail_after(20):
        await wait_for(lambda: bridge.server_ready("action", FIB, "fibonacci_stream"))
        node = RosAction(
            "stream",
            action_type=FIB,
            action_name="fibonacci_stream",
            bridge=bridge,
            server_timeout=FOUND_S,
            inputs={"order": 500},  # 500 feedback messages, ~1 ms apart
        )
        t0 = time.monotonic()
        state, ticks = await run_frozen(node)
        took = time.monotonic() - t0
    assert state is State.SUCCEEDED, node.error
    assert servers.events["fibonacci_stream.succeeded"] == 1
    # One tick per hand-over: the feedback's at most every FEEDBACK_WAKE_S, plus the first
    # tick, the goal's acceptance and its result (ticks can only be fewer on a slow run).
    assert ticks <= took / FEEDBACK_WAKE_S + 4, (ticks, took)
    assert ticks >= 3  # sent, accepted, result


def test_the_waker_coalesces_what_comes_before_the_loop_takes_it() -> None:
    loop = asyncio.new_event_loop()
    try:
        tree = Tree(Sequence("s"))
        waker = Waker(tree, loop)
        for _ in range(100):
            waker()
        assert waker.pending
        loop.call_soon(loop.stop)
        loop.run_forever()
        assert not waker.pending
        assert tree.alarm.nudged  # one nudge for the hundred
        waker(True)  # feedback right after a hand-over: not handed over
        assert not waker.pending
    finally:
        loop.close()


async def test_news_of_a_run_in_an_agents_slot_ticks_the_robots_tree(
    servers: Servers, bridge: RosBridge
) -> None:
    """The implementation's tree is ticked by the robot's host tree (its slot): the
    news of its RosAction ticks the host tree, whose clock never moves here."""
    iface = CapabilityInterface("Fib")
    impl = Implementation(
        "fib",
        iface,
        lambda: RosAction(
            "fib",
            action_type=FIB,
            action_name="fibonacci",
            bridge=bridge,
            server_timeout=FOUND_S,
            inputs={"order": 3},
        ),
    )
    with anyio.fail_after(20):
        await wait_for(lambda: bridge.server_ready("action", FIB, "fibonacci"))
        async with Agent("husky1", clock=ManualClock(), implementations=[impl]) as agent:
            slot = agent.mission_control.slot
            assert slot is not None
            run = impl.instantiate(agent.clock)
            hosted = Hosted(ExecutionId("x", "root", 1), run, {}, 1.0, 0.0, 10.0, started=True)
            assert slot.load(hosted) is None
            agent.host.nudge()  # the run's first tick; the rest comes from ROS's news
            await wait_for(lambda: run.tree.root.state in DONE)
            assert agent.clock.now() == 0.0
            assert run.tree.root.state is State.SUCCEEDED, run.tree.root.error
            slot.unload(hosted.execution)
            await run.close()
    assert servers.events["fibonacci.succeeded"] == 1
