"""Two robots in one process: the capability goes to whichever bids lower.

Run: .venv/bin/python examples/two_robots.py
"""

import asyncio

from btcap import Sequence, State
from btcap.team.demo import ECHO, implementations
from btcap.team.runtime.agent import Agent
from btcap.team.runtime.protocol import protocol_registry
from btcap.transports import InProcessNetwork


async def main() -> None:
    net = InProcessNetwork(protocol_registry())
    async with (
        Agent("base", transport=net.transport("base")) as base,
        Agent(
            "cheap",
            transport=net.transport("cheap"),
            implementations=implementations("cheap", cost=1.0),
        ),
        Agent(
            "dear",
            transport=net.transport("dear"),
            implementations=implementations("dear", cost=5.0),
        ),
    ):
        await asyncio.sleep(0.3)  # let heartbeats and repositories spread
        echo = ECHO.node_type()("echo", inputs={"value": 41})
        tree = base.mission(Sequence("mission", children=[echo]))
        for _ in range(20):
            tree.tick()
            await asyncio.sleep(0.05)
        print(echo.state, echo.outputs)  # running, echoed by robot 'cheap'
        echo.set_input("stop", True)
        state = await tree.run(20)
        print(state, echo.assignments)  # State.SUCCEEDED ['cheap']
        assert state is State.SUCCEEDED
        await tree.shutdown()


if __name__ == "__main__":
    asyncio.run(main())
