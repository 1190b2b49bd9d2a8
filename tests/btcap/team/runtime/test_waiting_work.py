"""Waiting work finds a robot as soon as the team knows what that robot can do.

A join is announced by the robot's heartbeat; its capabilities come in a message of their
own, which may arrive after the auction the join set off. Found with real sockets
(tests/btcap/team/deployment/test_partitions.py): after the operator's own partition
healed, its waiting task sat for the ``retry_s`` fallback (10 s) although every robot was
back.
"""

from __future__ import annotations

import anyio
from capfixtures import COUNT, Probe, count_impl, step, team, tick_until, until

from btcap import ReactiveSequence, State
from btcap.team.messages import RepositoryQuery, RepositoryState
from btcap.transports.codec import Envelope
from btcap.transports.inprocess import InProcessTransport


async def test_waiting_work_is_auctioned_when_a_joining_robots_capabilities_arrive() -> None:
    with anyio.fail_after(10):
        async with team() as t:
            held = True
            route = t.net._route

            def late_capabilities(src: InProcessTransport, env: Envelope) -> None:
                if not (held and src.system_id == "b" and isinstance(env.msg, RepositoryState)):
                    route(src, env)

            t.net._route = late_capabilities  # type: ignore[method-assign]
            a = await t.add("a")
            node = COUNT.node_type()("count", inputs={"x": 1, "stop": True}, retry_s=1000.0)
            tree = a.mission(ReactiveSequence("root", children=[node]))
            await t.add("b", [count_impl("b", 1.0, Probe())])
            await until(lambda: "b" in a.team.alive(), "a to see b join")
            for _ in range(10):  # the join's auction comes and goes without b's capabilities
                tree.tick()
                assert node.state is State.UNASSIGNED
                await step()
            held = False
            # b's state comes now, unchanged (b answers a query, or greets a rejoining a).
            a.system.ref("b/repository").tell(RepositoryQuery("a"))
            await until(lambda: "b" in a.repository.team, "a to learn b's capabilities")
            await tick_until(
                tree, lambda _s: node.state is not State.UNASSIGNED, "b to take it", limit=20
            )
            assert node.assignments == ["b"]
            await tree.shutdown()
