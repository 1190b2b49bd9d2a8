"""The departure log: who failed or left, which life, when and why; bounded; told to
members only; a warning once per failure when loud."""

from __future__ import annotations

from collections.abc import AsyncIterator
from contextlib import AsyncExitStack, asynccontextmanager

import anyio
from structlog.testing import capture_logs

from btcap.actors import ActorSystem, ManualClock
from btcap.team.membership.departures import DepartureLog
from btcap.team.membership.membership import Membership
from btcap.team.messages import Departed, Departures, DeparturesQuery, Goodbye, Heartbeat
from btcap.team.runtime.protocol import protocol_registry
from btcap.transports import Address, InProcessNetwork


@asynccontextmanager
async def robots(
    keep: int = 32,
) -> AsyncIterator[tuple[DepartureLog, ManualClock, dict[str, ActorSystem]]]:
    """Robot "me" with its membership and departure log; x and y send as themselves."""
    clock = ManualClock()
    net = InProcessNetwork(protocol_registry())
    async with AsyncExitStack() as stack:
        systems = {
            name: await stack.enter_async_context(
                ActorSystem(name, transport=net.transport(name), clock=clock)
            )
            for name in ("me", "x", "y")
        }
        team = Membership("me", heartbeat_s=0.1, failure_timeout_s=0.5)
        log = DepartureLog(team, keep=keep, loud=True)
        systems["me"].spawn(team, Membership.PATH)
        systems["me"].spawn(log, DepartureLog.PATH)
        yield log, clock, systems


async def test_failures_restarts_and_goodbyes_are_kept_with_their_life_and_why() -> None:
    with anyio.fail_after(5), capture_logs() as logs:
        async with robots() as (log, clock, systems):

            async def send(sender: str, msg: Heartbeat | Goodbye) -> None:
                systems[sender].tell(Address("me", Membership.PATH), msg)
                await clock.advance(0)

            await send("x", Heartbeat("x", 1, 0))
            await send("y", Heartbeat("y", 7, 0))
            await send("x", Heartbeat("x", 2, 0))  # x restarted
            await clock.advance(0.3)
            await send("x", Goodbye("x", 2))
            for _ in range(50):  # y answers no probe: suspected, then failed
                await clock.advance(0.1)
                if "y" not in log.team.members:
                    break
            await send("x", Heartbeat("x", 3, 0))  # x is back, a member again
            reply = await systems["x"].ask(Address("me", DepartureLog.PATH), DeparturesQuery())
    assert isinstance(reply, Departures)
    assert reply.robot == "me"
    assert [(d.robot, d.incarnation, d.how, d.why) for d in reply.departed] == [
        ("y", 7, "failed", "stopped answering probes (suspected, not refuted)"),
        ("x", 2, "left", "said goodbye"),
        ("x", 1, "failed", "restarted (a new life under the same name)"),
    ]
    assert reply.departed[1].age_ms >= 300  # the goodbye came 0.3 s before the silence
    failed = [e for e in logs if e["event"] == "team.member_failed"]
    assert [(e["member"], e["log_level"]) for e in failed] == [("x", "warning"), ("y", "warning")]
    assert [e["log_level"] for e in logs if e["event"] == "team.member_left"] == ["info"]


async def test_anyone_let_in_is_told_and_only_the_latest_are_kept() -> None:
    with anyio.fail_after(5):
        async with robots(keep=2) as (log, clock, systems):
            for life in range(1, 5):  # three restarts: three departures, two kept
                systems["x"].tell(Address("me", Membership.PATH), Heartbeat("x", life, 0))
                await clock.advance(0)
            # Not a member (an observer, say): told as well, as by the status desk; with
            # keys the transport's role table decides who may ask at all.
            stranger = await systems["y"].ask(Address("me", DepartureLog.PATH), DeparturesQuery())
            assert isinstance(stranger, Departures)
            reply = await systems["x"].ask(Address("me", DepartureLog.PATH), DeparturesQuery())
    assert isinstance(reply, Departures)
    assert [d.incarnation for d in reply.departed] == [3, 2]
    assert all(isinstance(d, Departed) and d.how == "failed" for d in reply.departed)
    assert len(log.departures) == 2
