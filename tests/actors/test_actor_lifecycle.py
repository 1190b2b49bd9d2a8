"""Spawning, naming, addresses, stopping and clean shutdown of an actor system."""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

import anyio
import pytest
from hypothesis import given
from hypothesis import strategies as st
from structlog.testing import capture_logs

from btcap.actors import (
    Actor,
    ActorSystem,
    Address,
    DeadLetter,
    Message,
    SystemClosed,
    handler,
)
from btcap.transports import InProcessNetwork


class Ping(Message):
    pass


class Wait(Message):
    pass


class Noted(Actor):
    """Records its start and stop in a shared journal."""

    def __init__(self, journal: list[str] | None = None) -> None:
        super().__init__()
        self.journal = journal if journal is not None else []

    def on_start(self) -> None:
        self.journal.append(f"start {self.address.path}")

    def on_stop(self) -> None:
        self.journal.append(f"stop {self.address.path}")

    @handler
    def on_ping(self, msg: Ping) -> str:
        return self.address.path


class Worker(Noted):
    """Runs a background task forever and blocks asks of ``Wait`` until cancelled."""

    def __init__(self, journal: list[str]) -> None:
        super().__init__(journal)
        self.task: asyncio.Task[None] | None = None
        self.ticks = 0
        self.ticking = asyncio.Event()
        self.waiting = asyncio.Event()

    def on_start(self) -> None:
        super().on_start()
        self.task = self.start_task(self._tick())

    async def _tick(self) -> None:
        while True:
            self.ticks += 1
            self.ticking.set()
            await asyncio.sleep(0.001)

    @handler
    async def on_wait(self, msg: Wait) -> None:
        self.waiting.set()
        await asyncio.Event().wait()


class BadStop(Noted):
    def on_stop(self) -> None:
        super().on_stop()
        raise RuntimeError("on_stop broke")


class TellsOnStop(Noted):
    """Tells another actor (with an async handler) while the system is closing."""

    def __init__(self, journal: list[str], target: Actor) -> None:
        super().__init__(journal)
        self.target = target

    def on_stop(self) -> None:
        super().on_stop()
        self.target.ref.tell(Wait())


class FailsToStart(Actor):
    def on_start(self) -> None:
        raise RuntimeError("no start")


@asynccontextmanager
async def no_task_left_behind() -> AsyncIterator[None]:
    """Fails if the block leaves any asyncio task running."""
    before = asyncio.all_tasks()
    yield
    assert asyncio.all_tasks() == before


# -- spawn, names, paths --------------------------------------------------------------------


async def test_spawn_names_paths_and_refs() -> None:
    with anyio.fail_after(2):
        async with ActorSystem("s") as system:
            auto = system.spawn(Noted())
            assert auto.address == Address("s", "noted-1")
            parent = Noted()
            pref = system.spawn(parent, "parent")
            child_actor = Noted()
            child = system.spawn(child_actor, "child", parent=parent)
            grandchild = system.spawn(Noted(), parent=child_actor)
            assert pref.address == Address("s", "parent")
            assert child.address == Address("s", "parent/child")
            assert str(child.address) == "s/parent/child"
            assert str(grandchild.address).startswith("s/parent/child/noted-")
            assert child_actor.parent is parent
            assert parent.parent is None
            assert len(system) == 4
            # Every way of naming the child reaches the same actor.
            assert await system.ref("s/parent/child").ask(Ping()) == "parent/child"
            assert await system.ref(Address("s", "parent/child")).ask(Ping()) == "parent/child"
            assert await system.ref("parent").ask(Ping()) == "parent"  # bare name: local
            assert system.ref("s/parent/child") == child
            assert system.ref("s/parent/child").is_local
            assert not system.ref("t/parent/child").is_local
            assert system.lookup("parent/child") is child_actor


async def test_spawn_rejects_bad_names_and_duplicates() -> None:
    with anyio.fail_after(2):
        async with ActorSystem("s") as system:
            parent = Noted()
            system.spawn(parent, "dup")
            with pytest.raises(ValueError, match="already lives at s/dup"):
                system.spawn(Noted(), "dup")
            system.spawn(Noted(), "kid", parent=parent)
            with pytest.raises(ValueError, match="already lives at s/dup/kid"):
                system.spawn(Noted(), "kid", parent=parent)
            for bad in ("", "a/b"):
                with pytest.raises(ValueError, match="actor name"):
                    system.spawn(Noted(), bad)
            with pytest.raises(ValueError, match="already spawned"):
                system.spawn(parent, "again")
            async with ActorSystem("t") as other:
                with pytest.raises(ValueError, match="same system"):
                    other.spawn(Noted(), "x", parent=parent)
            assert len(system) == 2


async def test_spawn_whose_on_start_raises_leaves_nothing_behind() -> None:
    with anyio.fail_after(2):
        async with ActorSystem("s") as system:
            with pytest.raises(RuntimeError, match="no start"):
                system.spawn(FailsToStart(), "x")
            assert system.lookup("x") is None
            assert len(system) == 0


def test_unspawned_actor_has_no_address() -> None:
    actor = Noted()
    assert not actor.spawned
    with pytest.raises(RuntimeError, match="not spawned"):
        _ = actor.address
    with pytest.raises(RuntimeError, match="not spawned"):
        _ = actor.system


def test_system_ids_are_validated() -> None:
    for bad in ("a/b", "*"):
        with pytest.raises(ValueError, match="system id"):
            ActorSystem(bad)
    net = InProcessNetwork()
    with pytest.raises(ValueError, match="differs from the transport"):
        ActorSystem("a", transport=net.transport("b"))
    assert ActorSystem(transport=net.transport("c")).id == "c"
    assert ActorSystem().id != ActorSystem().id  # random ids, no shared state


# -- addresses ------------------------------------------------------------------------------

system_ids = st.text(min_size=1).filter(lambda s: "/" not in s)
paths = st.text(min_size=1)


@given(system=system_ids, path=paths)
def test_address_str_and_parse_round_trip(system: str, path: str) -> None:
    address = Address(system, path)
    assert Address.parse(str(address)) == address


@pytest.mark.parametrize("text", ["", "no-slash", "/path", "system/", "/"])
def test_bad_address_strings_are_rejected_naming_the_text(text: str) -> None:
    with pytest.raises(ValueError, match="address") as err:
        Address.parse(text)
    assert repr(text) in str(err.value)


# -- stop ---------------------------------------------------------------------------------


async def test_stop_stops_children_first_and_fails_queued_asks() -> None:
    journal: list[str] = []
    with anyio.fail_after(2):
        async with ActorSystem("s") as system:
            parent = Noted(journal)
            system.spawn(parent, "p")
            child = Worker(journal)
            cref = system.spawn(child, "c", parent=parent)
            system.spawn(Noted(journal), "g", parent=child)
            unrelated = system.spawn(Noted(journal), "pp")  # a prefix, not a child
            in_flight = asyncio.ensure_future(cref.ask(Wait()))
            await child.waiting.wait()
            queued = asyncio.ensure_future(cref.ask(Ping()))
            await asyncio.sleep(0)
            journal.clear()
            system.stop(parent.ref)
            assert journal == ["stop p/c/g", "stop p/c", "stop p"]
            with pytest.raises(DeadLetter):
                await queued
            assert child.task is not None
            with pytest.raises(asyncio.CancelledError):
                await child.task  # the actor's own task was cancelled
            assert [system.lookup(p) for p in ("p", "p/c", "p/c/g")] == [None, None, None]
            assert await unrelated.ask(Ping()) == "pp"
            with pytest.raises(DeadLetter):
                await cref.ask(Ping())
            system.stop(parent)  # stopping again is a no-op
            assert journal == ["stop p/c/g", "stop p/c", "stop p"]
            in_flight.cancel()
            with pytest.raises(asyncio.CancelledError):
                await in_flight


# -- shutdown -------------------------------------------------------------------------------


async def test_leaving_the_block_stops_everything_and_leaves_no_tasks() -> None:
    journal: list[str] = []
    with anyio.fail_after(2):
        async with no_task_left_behind():
            async with ActorSystem("s") as system:
                root = Worker(journal)
                system.spawn(root, "root")
                system.spawn(Noted(journal), "leaf", parent=root)
                system.spawn(Noted(journal), "a-much-longer-top-level-name")
                own = system.start_task(asyncio.Event().wait(), name="system task")
                in_flight = asyncio.ensure_future(root.ref.ask(Wait()))
                await root.waiting.wait()
                queued = asyncio.ensure_future(root.ref.ask(Ping()))
                await root.ticking.wait()
                journal.clear()
            assert own.cancelled()
            assert root.task is not None
            assert root.task.cancelled()
            assert journal.index("stop root/leaf") < journal.index("stop root")
            assert sorted(journal) == sorted(
                ["stop root/leaf", "stop root", "stop a-much-longer-top-level-name"]
            )
            assert len(system) == 0
            assert not system.running
            with pytest.raises(SystemClosed):
                await in_flight  # its async handler was cancelled mid-way
            with pytest.raises(SystemClosed):
                await queued  # it never reached the handler
            with pytest.raises(SystemClosed):
                system.spawn(Noted(), "late")
            with pytest.raises(SystemClosed):
                await system.ask(Address("s", "root"), Ping())


async def test_a_failing_on_stop_is_logged_and_shutdown_goes_on() -> None:
    journal: list[str] = []
    with anyio.fail_after(2), capture_logs() as logs:
        async with ActorSystem("s") as system:
            system.spawn(BadStop(journal), "bad")
            system.spawn(Noted(journal), "good")
    assert sorted(journal) == ["start bad", "start good", "stop bad", "stop good"]
    assert [e["actor"] for e in logs if e["event"] == "actor.on_stop_failed"] == ["s/bad"]


async def test_telling_during_shutdown_never_raises() -> None:
    journal: list[str] = []
    with anyio.fail_after(2), capture_logs() as logs:
        async with no_task_left_behind(), ActorSystem("s") as system:
            target = Worker(journal)
            system.spawn(target, "target")
            system.spawn(TellsOnStop(journal, target), "a-longer-name-stops-first")
    assert "stop a-longer-name-stops-first" in journal
    assert [e for e in logs if e["event"] == "actor.on_stop_failed"] == []


async def test_failing_background_task_is_logged() -> None:
    async def broken() -> None:
        raise RuntimeError("task broke")

    with anyio.fail_after(2), capture_logs() as logs:
        async with ActorSystem("s") as system:
            task = system.start_task(broken(), name="broken")
            with pytest.raises(RuntimeError):
                await task
    assert [e["task"] for e in logs if e["event"] == "actors.task_failed"] == ["broken"]


async def test_cancelling_the_users_task_closes_the_system_cleanly() -> None:
    journal: list[str] = []
    entered = asyncio.Event()

    async def user_code() -> None:
        async with ActorSystem("s") as system:
            system.spawn(Worker(journal), "w")
            entered.set()
            await asyncio.Event().wait()

    with anyio.fail_after(2):
        async with no_task_left_behind():
            task = asyncio.create_task(user_code())
            await entered.wait()
            task.cancel()
            with pytest.raises(asyncio.CancelledError):
                await task
    assert journal == ["start w", "stop w"]


async def test_a_timeout_around_the_block_closes_the_system_cleanly() -> None:
    journal: list[str] = []

    async def run() -> None:
        with anyio.fail_after(0.02):
            async with ActorSystem("s") as system:
                system.spawn(Worker(journal), "w")
                await asyncio.Event().wait()

    with anyio.fail_after(2):
        async with no_task_left_behind():
            with pytest.raises(TimeoutError):
                await run()
    assert journal == ["start w", "stop w"]


async def test_the_blocks_own_exception_propagates_unwrapped() -> None:
    async def run() -> None:
        async with ActorSystem("s") as system:
            system.spawn(Noted(), "n")
            raise LookupError("mine")

    with anyio.fail_after(2), pytest.raises(LookupError, match="mine"):
        await run()


async def test_aclose_is_idempotent_and_a_system_cannot_be_entered_twice() -> None:
    with anyio.fail_after(2):
        system = ActorSystem("s")
        async with system:
            with pytest.raises(RuntimeError, match="already running"):
                await system.__aenter__()
            await system.aclose()
            await system.aclose()
            assert not system.running
