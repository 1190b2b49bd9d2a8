"""Supervision policies: what happens to an actor (and its asker) when a handler raises."""

from __future__ import annotations

import asyncio
from typing import Any, ClassVar

import anyio
import pytest
from structlog.testing import capture_logs

from btcap.actors import (
    Actor,
    ActorError,
    ActorFailed,
    ActorSystem,
    DeadLetter,
    Message,
    Supervision,
    handler,
)


class Add(Message):
    k: int


class Boom(Message):
    why: str = "boom"


class AsyncBoom(Message):
    why: str = "async boom"


class Fragile(Actor):
    """Counts, fails on request, and records every lifecycle hook."""

    supervision: ClassVar[Supervision] = Supervision.RESUME

    def __init__(self, journal: list[str] | None = None) -> None:
        super().__init__()
        self.count = 0
        self.restarted_by: list[BaseException] = []
        self.stopped = 0
        self.journal = journal if journal is not None else []

    @handler
    def on_add(self, msg: Add) -> int:
        self.count += msg.k
        return self.count

    @handler
    def on_boom(self, msg: Boom) -> None:
        raise ValueError(msg.why)

    @handler
    async def on_async_boom(self, msg: AsyncBoom) -> None:
        await asyncio.sleep(0)
        raise ValueError(msg.why)

    def on_restart(self, error: BaseException) -> None:
        self.restarted_by.append(error)
        self.count = 0
        self.journal.append(f"restart {self.address.path}")

    def on_stop(self) -> None:
        self.stopped += 1
        self.journal.append(f"stop {self.address.path}")


class Resuming(Fragile):
    supervision = Supervision.RESUME


class Restarting(Fragile):
    supervision = Supervision.RESTART
    max_restarts = 2


class Stopping(Fragile):
    supervision = Supervision.STOP


class Escalating(Fragile):
    supervision = Supervision.ESCALATE


class BadRestart(Fragile):
    supervision = Supervision.RESTART

    def on_restart(self, error: BaseException) -> None:
        raise RuntimeError("cannot restart")


POLICIES: list[type[Fragile]] = [Resuming, Restarting, Stopping, Escalating]


async def _ask_failing(system: ActorSystem, actor_type: type[Fragile], msg: Any) -> ActorFailed:
    ref = system.spawn(actor_type(), "fragile")
    with pytest.raises(ActorFailed) as err:
        await ref.ask(msg)
    return err.value


@pytest.mark.parametrize("msg", [Boom("bad"), AsyncBoom("bad")], ids=["sync", "async"])
@pytest.mark.parametrize("actor_type", POLICIES, ids=lambda t: t.supervision.value)
async def test_ask_whose_handler_raised_gets_actor_failed_under_every_policy(
    actor_type: type[Fragile], msg: Message
) -> None:
    with anyio.fail_after(2):
        if actor_type.supervision is Supervision.ESCALATE:
            with pytest.raises(ActorError, match="escalated"):
                async with ActorSystem("s") as system:
                    failure = await _ask_failing(system, actor_type, msg)
        else:
            async with ActorSystem("s") as system:
                failure = await _ask_failing(system, actor_type, msg)
    assert failure.error_type == "ValueError"
    assert failure.detail == "bad"
    assert failure.address == "s/fragile"


async def test_handler_failure_is_logged_with_actor_and_message() -> None:
    with anyio.fail_after(2), capture_logs() as logs:
        async with ActorSystem("s") as system:
            ref = system.spawn(Resuming(), "fragile")
            ref.tell(Boom())
            ref.tell(AsyncBoom())
            await ref.ask(Add(0))  # queued behind AsyncBoom: the failure has happened
    failures = [e for e in logs if e["event"] == "actor.handler_failed"]
    assert [(e["actor"], e["message"], e["policy"]) for e in failures] == [
        ("s/fragile", "Boom", "resume"),
        ("s/fragile", "AsyncBoom", "resume"),
    ]
    assert all(e["log_level"] == "error" for e in failures)
    assert all(isinstance(e["exc_info"], ValueError) for e in failures)


async def test_resume_keeps_state_and_goes_on() -> None:
    with anyio.fail_after(2):
        async with ActorSystem("s") as system:
            actor = Resuming()
            ref = system.spawn(actor, "r")
            ref.tell(Add(5))
            ref.tell(Boom())
            ref.tell(AsyncBoom())
            assert await ref.ask(Add(1)) == 6
            assert actor.restarted_by == []
            assert actor.stopped == 0
            assert system.lookup("r") is actor


async def test_restart_calls_on_restart_then_stops_after_max_restarts() -> None:
    with anyio.fail_after(2):
        async with ActorSystem("s") as system:
            actor = Restarting()
            ref = system.spawn(actor, "r")
            ref.tell(Add(5))
            ref.tell(Boom("first"))
            assert [str(e) for e in actor.restarted_by] == ["first"]
            assert actor.count == 0  # on_restart reset the state
            assert await ref.ask(Add(2)) == 2
            with pytest.raises(ActorFailed):
                await ref.ask(AsyncBoom("second"))
            assert [str(e) for e in actor.restarted_by] == ["first", "second"]
            assert system.lookup("r") is actor  # max_restarts = 2: still alive
            ref.tell(Boom("third"))
            assert len(actor.restarted_by) == 2  # no third restart ...
            assert actor.stopped == 1  # ... the actor was stopped instead
            assert system.lookup("r") is None
            with pytest.raises(DeadLetter):
                await ref.ask(Add(1))
        assert actor.stopped == 1  # on_stop ran exactly once


async def test_failing_on_restart_stops_the_actor() -> None:
    with anyio.fail_after(2), capture_logs() as logs:
        async with ActorSystem("s") as system:
            actor = BadRestart()
            ref = system.spawn(actor, "r")
            ref.tell(Boom())
            assert system.lookup("r") is None
            assert actor.stopped == 1
    assert any(e["event"] == "actor.restart_failed" and e["actor"] == "s/r" for e in logs)


async def test_stop_stops_the_actor_and_fails_what_it_had_queued() -> None:
    with anyio.fail_after(2):
        async with ActorSystem("s") as system:
            actor = Stopping()
            ref = system.spawn(actor, "x")
            ref.tell(AsyncBoom())  # queued: async handler
            queued = asyncio.ensure_future(ref.ask(Add(1)))  # queued behind it
            with pytest.raises(DeadLetter, match="s/x was stopped"):
                await queued
            assert actor.stopped == 1
            assert system.lookup("x") is None
            before = system.stats.dead_letters
            ref.tell(Add(1))
            assert system.stats.dead_letters == before + 1


async def test_escalate_fails_the_parent_with_the_childs_error() -> None:
    with anyio.fail_after(2):
        async with ActorSystem("s") as system:
            parent = Restarting()
            system.spawn(parent, "parent")
            child = Escalating()
            ref = system.spawn(child, "child", parent=parent)
            parent.count = 7
            ref.tell(Boom("from child"))
            assert child.stopped == 1
            assert system.lookup("parent/child") is None
            assert [str(e) for e in parent.restarted_by] == ["from child"]
            assert parent.count == 0
            assert system.lookup("parent") is parent  # the parent restarted, not stopped


async def test_escalation_climbs_until_a_policy_handles_it() -> None:
    journal: list[str] = []
    with anyio.fail_after(2):
        async with ActorSystem("s") as system:
            root = Stopping(journal)
            system.spawn(root, "root")
            middle = Escalating(journal)
            system.spawn(middle, "mid", parent=root)
            leaf = Escalating(journal)
            system.spawn(leaf, "leaf", parent=middle)
            sibling = Resuming(journal)
            system.spawn(sibling, "sibling")
            await leaf.ref.ask(Add(1))
            leaf.ref.tell(AsyncBoom())
            with pytest.raises(DeadLetter):  # queued behind the failure that stops it
                await leaf.ref.ask(Add(1))
            assert system.lookup("root") is None
            assert journal == ["stop root/mid/leaf", "stop root/mid", "stop root"]
            assert system.lookup("sibling") is sibling
            assert system.stats.escalations == 0  # handled below the top
        assert journal[-1] == "stop sibling"


@pytest.mark.parametrize("msg", [Boom(), AsyncBoom()], ids=["sync", "async"])
async def test_top_level_escalation_interrupts_the_block_and_raises_actor_error(
    msg: Message,
) -> None:
    reached_end = False
    before = asyncio.all_tasks()
    system = ActorSystem("s")
    actor, other = Escalating(), Resuming()

    async def run() -> None:
        nonlocal reached_end
        async with system:
            system.spawn(actor, "top")
            system.spawn(other, "other")
            system.ref("s/top").tell(msg)
            await asyncio.Event().wait()  # only the escalation ends this
            reached_end = True

    with anyio.fail_after(2), pytest.raises(ActorError, match="actor s/top escalated") as err:
        await run()
    assert not reached_end
    assert isinstance(err.value.__cause__, ValueError)
    assert system.stats.escalations == 1
    assert actor.stopped == 1
    assert other.stopped == 1  # the whole system shut down cleanly
    assert asyncio.all_tasks() == before


async def test_top_level_escalation_without_a_later_await_still_raises() -> None:
    async def run() -> None:
        async with ActorSystem("s") as system:
            system.spawn(Escalating(), "top").tell(Boom("late"))

    with anyio.fail_after(2), pytest.raises(ActorError) as err:
        await run()
    assert str(err.value.__cause__) == "late"


async def test_the_blocks_own_error_wins_over_an_escalation() -> None:
    async def run() -> None:
        async with ActorSystem("s") as system:
            system.spawn(Escalating(), "top").tell(Boom())
            raise KeyError("mine")

    with anyio.fail_after(2), pytest.raises(KeyError):
        await run()
