"""Team membership: joins, goodbyes, silent failures, restarts; unit and between agents."""

from __future__ import annotations

from collections.abc import AsyncIterator
from contextlib import AsyncExitStack, asynccontextmanager
from typing import Any

import anyio
import pytest
from capfixtures import COUNT, Probe, count_impl, team, tick_until, until

from btcap import ReactiveSequence
from btcap.actors import Actor, ActorSystem, ManualClock, handler
from btcap.team.deployment.deploy import observe_team
from btcap.team.membership.membership import MAX_ANSWERS_DUE, Membership, TeamEvent
from btcap.team.messages import (
    Contact,
    Goodbye,
    Heard,
    Heartbeat,
    ProbeRequest,
    Roster,
    RosterRequest,
    Vouch,
)
from btcap.team.runtime.protocol import protocol_registry
from btcap.transports import Address, InProcessNetwork, Message


class Peers:
    """Robots x and y as actor systems of their own: what they send, the network
    delivers with their authenticated name, whatever the message claims."""

    def __init__(self, m: Membership, clock: ManualClock, systems: dict[str, ActorSystem]):
        self.m, self.clock, self.systems = m, clock, systems

    async def send(self, sender: str, msg: Message) -> None:
        self.systems[sender].tell(Address("me", Membership.PATH), msg)
        await self.clock.advance(0)  # the network delivers on the next loop turn


@asynccontextmanager
async def membership(**kw: Any) -> AsyncIterator[tuple[Peers, list[tuple[TeamEvent, str]]]]:
    clock = ManualClock()
    net = InProcessNetwork(protocol_registry())
    async with AsyncExitStack() as stack:
        systems = {
            name: await stack.enter_async_context(
                ActorSystem(name, transport=net.transport(name), clock=clock)
            )
            for name in ("me", "x", "y")
        }
        m = Membership("me", **kw)
        systems["me"].spawn(m, Membership.PATH)
        events: list[tuple[TeamEvent, str]] = []
        m.subscribe(lambda e, r: events.append((e, r)))
        yield Peers(m, clock, systems), events


def test_failure_timeout_must_exceed_the_heartbeat() -> None:
    with pytest.raises(ValueError, match="failure_timeout_s"):
        Membership("me", heartbeat_s=1.0, failure_timeout_s=1.0)


async def test_heartbeats_join_change_and_restart() -> None:
    with anyio.fail_after(5):
        async with membership() as (p, events):
            m = p.m
            m.system.tell(m.address, Heartbeat("me", m.incarnation, 0))  # my own: ignored
            await p.clock.advance(0)
            assert events == []
            assert m.alive() == {"me"}
            await p.send("x", Heartbeat("x", 1, 0))
            await p.send("x", Heartbeat("x", 1, 0))  # nothing new
            assert events == [(TeamEvent.JOINED, "x")]
            assert m.alive() == {"me", "x"}
            await p.send("x", Heartbeat("x", 1, 3))
            assert events[-1] == (TeamEvent.CHANGED, "x")
            # A new incarnation: the old one failed, the new one joined.
            await p.send("x", Heartbeat("x", 2, 0))
            assert events[-2:] == [(TeamEvent.FAILED, "x"), (TeamEvent.JOINED, "x")]
            assert m.members["x"].incarnation == 2


async def test_a_robot_speaks_only_for_itself() -> None:
    with anyio.fail_after(5):
        async with membership() as (p, events):
            await p.send("x", Heartbeat("x", 1, 0))
            await p.send("y", Heartbeat("z", 1, 0))  # y in z's name: no z joins
            await p.send("y", Goodbye("x", 1))  # y in x's name: x stays
            assert events == [(TeamEvent.JOINED, "x")]
            assert p.m.alive() == {"me", "x"}
            assert p.m.refused == 2


async def test_goodbye_of_the_current_incarnation_only() -> None:
    with anyio.fail_after(5):
        async with membership() as (p, events):
            await p.send("x", Heartbeat("x", 2, 0))
            await p.send("x", Goodbye("x", 1))  # from an old incarnation
            await p.send("y", Goodbye("y", 1))  # from a stranger
            assert p.m.alive() == {"me", "x"}
            await p.send("x", Goodbye("x", 2))
            assert events == [(TeamEvent.JOINED, "x"), (TeamEvent.LEFT, "x")]
            assert p.m.alive() == {"me"}


async def test_a_member_silent_to_probes_is_suspected_then_failed() -> None:
    with anyio.fail_after(5):
        async with membership(heartbeat_s=0.1, failure_timeout_s=0.5) as (p, events):
            x = Asked()
            p.systems["x"].spawn(x, Membership.PATH)
            await confirmed(p, x)  # x answers the probe its join brought, then no other
            await p.clock.advance(0.4)
            await p.send("x", Heartbeat("x", 1, 0))  # its own word ends the suspicion
            assert p.m.table.suspected == {}
            await p.clock.advance(0.2)  # the next probe went unanswered: suspected
            assert set(p.m.table.suspected) == {"x"}
            await p.clock.advance(0.3)  # not yet: the suspicion lasts failure_timeout_s
            # each suspicion is news (auctions stop waiting for x), not a failure
            suspected = [(TeamEvent.JOINED, "x"), *[(TeamEvent.SUSPECTED, "x")] * 2]
            assert events == suspected
            await p.clock.advance(0.4)
            assert events == [*suspected, (TeamEvent.FAILED, "x")]
            assert p.m.alive() == {"me"}


async def test_only_members_may_ask_for_a_probe_or_vouch() -> None:
    with anyio.fail_after(5):
        async with membership() as (p, events):
            await p.send("x", Heartbeat("x", 1, 0))
            await p.send("y", ProbeRequest("x", 1))  # y is no member: refused
            await p.send("y", Vouch("x", 1, 1, 0))
            assert p.m.refused == 2
            await p.send("x", ProbeRequest("ghost", 1))  # a member, about a stranger: ignored
            await p.send("x", Vouch("x", 99, 1, 0))  # not asked: changes nothing
            assert p.m.refused == 2
            assert events == [(TeamEvent.JOINED, "x")]


async def test_a_failing_listener_does_not_stop_the_others() -> None:
    with anyio.fail_after(5):
        async with membership() as (p, events):

            def bad(_e: TeamEvent, _r: str) -> None:
                raise RuntimeError("listener bug")

            unsubscribe = p.m.subscribe(bad)
            p.m.subscribe(lambda e, r: events.append((e, r)))
            await p.send("x", Heartbeat("x", 1, 0))
            assert events == [(TeamEvent.JOINED, "x"), (TeamEvent.JOINED, "x")]
            unsubscribe()
            unsubscribe()  # twice is harmless
            assert bad not in p.m._listeners


async def test_join_leave_and_failure_between_agents() -> None:
    with anyio.fail_after(10):
        async with team() as t:
            a = await t.add("a")
            await t.add("b")
            await t.add("c")
            await t.converged()
            assert t.seen("a", "b") == [TeamEvent.JOINED]
            # b leaves on purpose: everyone knows at once (no timeout needed).
            await t.remove("b")
            await until(lambda: a.team.alive() == {"a", "c"} and t["c"].team.alive() == {"a", "c"})
            assert t.seen("a", "b") == [TeamEvent.JOINED, TeamEvent.LEFT]
            # c goes silent: after the failure timeout it counts as failed, and c sees a fail.
            t.net.isolate("c")
            await until(lambda: a.team.alive() == {"a"} and t["c"].team.alive() == {"c"})
            # (suspected first: the news auctions stop waiting on)
            gone = [TeamEvent.JOINED, TeamEvent.SUSPECTED, TeamEvent.FAILED]
            assert t.seen("a", "c") == gone
            assert t.seen("c", "a") == gone
            # Healed, it joins again.
            t.net.heal("c")
            await until(lambda: a.team.alive() == {"a", "c"})
            assert t.seen("a", "c") == [*gone, TeamEvent.JOINED]


async def test_restart_with_a_new_incarnation_counts_as_fail_and_join() -> None:
    # The failure timeout is long: only the new incarnation can reveal the restart.
    with anyio.fail_after(10):
        async with team(failure_timeout_s=1000.0) as t:
            probe = Probe()
            a = await t.add("a")
            b = await t.add(
                "b", [count_impl("b", 1.0, probe), count_impl("b", 1.0, probe, name="x")]
            )
            await t.converged()
            for i in range(3):  # the old incarnation's repository version grows past the new one's
                b.repository.record_success(f"Cap{i}")
            await until(lambda: a.repository.team["b"].version == b.repository.version)
            old = b.team.incarnation
            t.net.isolate("b")  # a crash: no goodbye gets out
            await t.remove("b")
            assert a.team.alive() == {"a", "b"}
            b2 = await t.add("b")
            assert b2.team.incarnation != old
            await until(lambda: a.team.members["b"].incarnation == b2.team.incarnation)
            joins = [e for e in t.seen("a", "b") if e is not TeamEvent.CHANGED]
            assert joins == [TeamEvent.JOINED, TeamEvent.FAILED, TeamEvent.JOINED]
            # What the old incarnation could do and did is forgotten; the new one is learnt.
            await until(lambda: "b" in a.repository.team)
            assert a.repository.team["b"].version == b2.repository.version
            assert a.repository.providers(COUNT.identity) == set()
            assert not a.repository.succeeded_anywhere("Cap0")


async def test_an_observer_sees_what_each_member_runs() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team() as t:
            a = await t.add("a")
            b = await t.add("b", [count_impl("b", 1.0, probe)])
            await t.converged()
            node = COUNT.node_type()("count", inputs={"x": 1})
            tree = a.mission(ReactiveSequence("root", children=[node]))
            await tick_until(tree, lambda _s: b.mission_control.body.running is not None, "b runs")
            seen = {m.robot: m for m in await observe_team(a)}
            assert seen["b"].running == [str(b.mission_control.body.running)]
            assert seen["b"].running[0].startswith("a~")  # a's work (a~<incarnation>:…), on b
            assert "Count" in (seen["b"].capabilities or {})
            observer = await t.add("observer")
            await t.converged()
            views = {m.robot: m.running for m in await observe_team(observer)}
            assert views == {"a": [], "b": seen["b"].running}
            await tree.shutdown()


async def test_a_roster_nobody_asked_for_is_refused() -> None:
    """Only a robot that just met us (its welcome) or that we asked may make us dial."""
    with anyio.fail_after(10):
        async with team() as t:
            a = await t.add("a")
            c = await t.add("c")
            await t.converged()
            await t.clock.sleep(2 * a.team.failure_timeout_s)  # past the welcome
            refused = a.team.refused
            c.system.tell(
                Address("a", Membership.PATH), Roster([Contact("ghost", "tcp://127.0.0.1:9")])
            )
            await until(lambda: a.team.refused == refused + 1, "the roster refused")


async def test_a_welcome_is_taken_however_late_but_once_per_join() -> None:
    """How soon a member learns of us depends on gossip and load: its welcome roster is
    taken whenever it comes (a deadline refused it under load, with a warning), but a
    member gets one unasked roster per join, no more."""
    with anyio.fail_after(5):
        async with membership(heartbeat_s=0.1, failure_timeout_s=0.5) as (p, events):
            await p.send("x", Heartbeat("x", 1, 0))
            for _ in range(10):  # 2 s, four failure timeouts: x stays a member
                await p.clock.advance(0.2)
                await p.send("x", Heartbeat("x", 1, 0))
            assert events == [(TeamEvent.JOINED, "x")]
            await p.send("x", Roster([Contact("y", "inproc://y")]))
            assert p.m.refused == 0
            await p.send("x", Roster([Contact("y", "inproc://y")]))
            assert p.m.refused == 1
            await p.send("x", Heartbeat("x", 2, 0))  # a new life joins: one welcome more
            await p.send("x", Roster([]))
            await p.send("x", Roster([]))
            assert p.m.refused == 2


async def test_an_unasked_roster_naming_nobody_new_is_refused_without_a_warning() -> None:
    """A robot the others declared failed while it kept them is welcomed again by each:
    those rosters are refused (counted) but name nobody it would dial, so they are no
    warning; one naming a robot it does not know still is."""
    from structlog.testing import capture_logs

    with anyio.fail_after(5):
        async with membership(heartbeat_s=0.1, failure_timeout_s=0.5) as (p, _events):
            await p.send("x", Heartbeat("x", 1, 0))
            await p.send("x", Roster([]))  # its welcome
            with capture_logs() as logs:
                await p.send("x", Roster([Contact("x", "inproc://x")]))  # known only
                await p.send("x", Roster([]))
                assert p.m.refused == 2
                assert [e["log_level"] for e in logs if e["event"] == "team.refused"] == [
                    "debug",
                    "debug",
                ]
                await p.send("x", Roster([Contact("y", "inproc://y")]))  # would dial y
            assert p.m.refused == 3
            assert [e["log_level"] for e in logs if e["event"] == "team.refused"][-1] == "warning"


class Asked(Actor):
    """A peer's membership that only notes the roster requests and probes it gets."""

    def __init__(self) -> None:
        super().__init__()
        self.requests: list[list[str]] = []
        self.probes: list[int] = []

    @handler
    def on_roster_request(self, msg: RosterRequest) -> None:
        self.requests.append(list(msg.robots))

    @handler
    def on_heartbeat(self, msg: Heartbeat) -> None:
        if msg.probe:
            self.probes.append(msg.probe)

    @handler
    def on_roster(self, msg: Roster) -> None:
        pass


async def confirmed(p: Peers, x: Asked, incarnation: int = 1) -> None:
    """x joins and answers the probe its join brought: from then on its news counts."""
    await p.send("x", Heartbeat("x", incarnation, 0))
    await p.clock.advance(0)  # our probe reaches x
    await p.send("x", Heartbeat("x", incarnation, 0, ack=x.probes[-1]))
    assert "x" not in p.m.swim.newcomers


def mentioning(*robots: str, incarnation: int = 1) -> Heartbeat:
    """x's heartbeat with news of ``robots`` (no peers of ours: we must ask x where)."""
    return Heartbeat("x", incarnation, 0, False, 0, [Heard(r, 1, 0) for r in robots])


async def test_a_member_owes_its_welcome_and_an_answer_to_each_request() -> None:
    """x's news names robots we cannot reach, so we ask x where they are (once now, once
    a little later for another) while its welcome is still on its way: its welcome and
    both answers are taken, in whatever order they come; a roster more is refused."""
    with anyio.fail_after(5):
        async with membership(heartbeat_s=0.1, failure_timeout_s=0.5) as (p, _):
            x = Asked()
            p.systems["x"].spawn(x, Membership.PATH)
            await confirmed(p, x)
            await p.send("x", mentioning("z1"))
            await p.clock.advance(0.05)
            await p.send("x", mentioning("z2"))
            assert x.requests == [["z1"], ["z2"]]
            await p.send("x", Roster([Contact("z1", "inproc://z1")]))  # an answer
            await p.send("x", Roster([]))  # the welcome
            await p.send("x", Roster([Contact("z2", "inproc://z2")]))  # the other answer
            assert p.m.refused == 0
            await p.send("x", Roster([Contact("z3", "inproc://z3")]))  # more than we asked
            assert p.m.refused == 1


async def test_an_answer_is_due_until_the_failure_timeout_the_welcome_until_taken() -> None:
    with anyio.fail_after(5):
        async with membership(heartbeat_s=0.1, failure_timeout_s=0.5) as (p, _):
            x = Asked()
            p.systems["x"].spawn(x, Membership.PATH)
            await confirmed(p, x)
            await p.send("x", mentioning("z1"))
            assert x.requests == [["z1"]]
            await p.clock.advance(0.6)  # the answer is late: refused; the welcome is not
            await p.send("x", Heartbeat("x", 1, 0))
            await p.send("x", Roster([]))
            await p.send("x", Roster([]))
            assert p.m.refused == 1


async def test_what_a_member_may_owe_us_is_bounded_and_forgotten_when_it_leaves() -> None:
    """However many robots x names, at most MAX_ANSWERS_DUE requests to it are open
    (the other robots are asked about once an answer came), so x can make us take at
    most that many rosters plus its welcome; what its life owed is gone with it."""
    with anyio.fail_after(5):
        async with membership(heartbeat_s=0.1, failure_timeout_s=0.5) as (p, _):
            x = Asked()
            p.systems["x"].spawn(x, Membership.PATH)
            await confirmed(p, x)
            for i in range(2 * MAX_ANSWERS_DUE):
                await p.send("x", mentioning(f"z{i}"))
            assert x.requests == [[f"z{i}"] for i in range(MAX_ANSWERS_DUE)]
            await p.send("x", Roster([]))  # an answer: room for one question more
            await p.send("x", mentioning("z0", "z9"))
            assert x.requests[-1] == ["z9"]  # z0 was asked about already
            for _ in range(MAX_ANSWERS_DUE + 2):
                await p.send("x", Roster([]))
            assert p.m.refused == 1  # the open answers and the welcome, then nothing
            await p.send("x", mentioning("y1"))
            await p.send("x", Goodbye("x", 1))
            await p.send("x", Heartbeat("x", 2, 0))  # a new life: only its welcome is due
            await p.send("x", Roster([]))
            await p.send("x", Roster([]))
            assert p.m.refused == 2
