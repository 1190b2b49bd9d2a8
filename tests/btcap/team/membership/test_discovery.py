"""Discovery over tcp loopback: one seed is enough to learn the whole team, the team learns
the newcomer, and losing the seed hangs nobody. Messages carry two news items each (a
fanout below the team's size), so news of joins, introductions and rosters do the work."""

from __future__ import annotations

from collections.abc import Callable, Iterator

import anyio
import anyio.abc
import pytest
from structlog.testing import capture_logs

from btcap.team.core.members import TeamEvent
from btcap.team.runtime.agent import Agent, AgentConfig
from btcap.team.runtime.protocol import protocol_registry
from btcap.transports import ZmqTransport

LOCAL = "tcp://127.0.0.1:*"
CONFIG = AgentConfig(heartbeat_s=0.05, failure_timeout_s=1.0, heartbeat_fanout=2)


@pytest.fixture(autouse=True)
def quiet_logs() -> Iterator[None]:
    with capture_logs():
        yield


class Robots:
    """Agents each running in a task of its own, so any one can stop while others run."""

    def __init__(self, tg: anyio.abc.TaskGroup) -> None:
        self.tg = tg
        self.agents: dict[str, Agent] = {}
        self.stops: dict[str, anyio.Event] = {}

    async def start(self, name: str, seeds: dict[str, str]) -> Agent:
        started = anyio.Event()
        self.stops[name] = anyio.Event()

        async def run() -> None:
            reg = protocol_registry()
            transport = ZmqTransport(name, LOCAL, reg, peers=seeds)
            async with Agent(name, transport=transport, registry=reg, config=CONFIG) as a:
                self.agents[name] = a
                started.set()
                await self.stops[name].wait()
            del self.agents[name]

        self.tg.start_soon(run)
        await started.wait()
        return self.agents[name]

    def stop(self, name: str) -> None:
        self.stops[name].set()

    def stop_all(self) -> None:
        for event in self.stops.values():
            event.set()


def endpoint(a: Agent) -> str:
    transport = a.system.transport
    assert isinstance(transport, ZmqTransport)
    return transport.endpoint


async def until(cond: Callable[[], bool], what: str) -> None:
    try:
        with anyio.fail_after(8):
            while not cond():  # noqa: ASYNC110 - views have no event to wait on
                await anyio.sleep(0.02)
    except TimeoutError:
        raise AssertionError(f"timed out: {what}") from None


def views(agents: list[Agent]) -> dict[str, frozenset[str]]:
    return {a.team.robot: a.team.alive() for a in agents}


async def test_one_seed_is_enough_and_losing_it_hangs_nobody() -> None:
    with anyio.fail_after(30):
        async with anyio.create_task_group() as tg:
            team = Robots(tg)
            seed = await team.start("s0", {})
            robots = [await team.start(f"r{i}", {"s0": endpoint(seed)}) for i in range(1, 6)]
            everyone = frozenset(team.agents)
            await until(
                lambda: all(v == everyone for v in views([seed, *robots]).values()),
                f"everybody knows everybody: {views([seed, *robots])}",
            )
            failures: list[str] = []
            for a in robots:
                a.team.subscribe(
                    lambda event, robot: (
                        failures.append(robot) if event is TeamEvent.FAILED else None
                    )
                )
            team.stop("s0")  # the seed leaves for good
            rest = everyone - {"s0"}
            await until(lambda: all(v == rest for v in views(robots).values()), "s0 left")
            # A latecomer that knows only r1 still meets everyone, and everyone meets it.
            late = await team.start("late", {"r1": endpoint(robots[0])})
            await until(
                lambda: all(v == rest | {"late"} for v in views([*robots, late]).values()),
                f"the latecomer is known to all: {views([*robots, late])}",
            )
            await anyio.sleep(2 * CONFIG.failure_timeout_s)  # nobody is falsely declared dead
            assert all(v == rest | {"late"} for v in views([*robots, late]).values())
            assert failures == []
            team.stop_all()
