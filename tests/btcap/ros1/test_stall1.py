"""The ROS 1 bridge never holds the tick on its rospy process: the process reads frames on
one thread, which stalls while rospy retries registering a publisher with a master that is
gone (until one answers). Writing to it from the tick then blocked the event loop as soon
as the pipe was full: here a dozen 20 kB messages."""

from __future__ import annotations

import threading

import anyio
import pytest
from rosmaster1 import Master
from tools1 import bridge_on, run

from btcap.bt.state import State
from btcap.bt.tree import Tree
from btcap.ros.nodes1 import RosPublish, RosWaitForMessage

pytestmark = pytest.mark.ros1

#: Ticks of the publisher while its process is stalled: far more than the pipe holds.
TICKS = 300
DEPTH = 5


async def test_a_stalled_rospy_process_never_holds_the_tick(master: Master) -> None:
    """The tick goes on while the process is stalled (the publisher's unsent messages kept
    to its queue size, oldest dropped, as rospy's own queue does); once a master answers
    again the process registers the publisher and its messages flow."""
    with anyio.fail_after(60):
        async with bridge_on(master) as bridge:
            await anyio.to_thread.run_sync(master.stop)
            pub = RosPublish(
                "say",
                topic_type="std_msgs/String",
                topic_name="big",
                rate_hz=1000.0,
                depth=DEPTH,
                bridge=bridge,
                inputs={"data": "x" * 20_000},
            )
            tree = Tree(pub)
            tree.setup()
            ticked = threading.Event()

            def watchdog() -> None:  # a blocked loop cannot end the test: end the stall
                if not ticked.wait(20.0) and bridge.process is not None:
                    bridge.process.kill()

            dog = threading.Thread(target=watchdog, daemon=True)
            dog.start()
            for _ in range(TICKS):
                assert tree.tick() is State.RUNNING, pub.error
                await anyio.sleep(0.001)
            ticked.set()
            dog.join()
            assert bridge._outbox is not None
            assert bridge._outbox.waiting() <= DEPTH + 2  # its Open, a frame begun
            await anyio.to_thread.run_sync(master.start)  # the same port: rospy retries it
            hear = RosWaitForMessage(
                "hear", topic_type="std_msgs/String", topic_name="big", bridge=bridge
            )
            Tree(hear).setup()
            while hear.state is not State.SUCCEEDED:
                assert tree.tick() is State.RUNNING, pub.error
                assert await run(hear, lambda s: True) is not State.FAILED, hear.error
                await anyio.sleep(0.005)
            assert len(hear.outputs["data"]) == 20_000
            await tree.shutdown()
