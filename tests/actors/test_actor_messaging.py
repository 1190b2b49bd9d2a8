"""tell/ask semantics, handler dispatch, the local fast path, ordering and mailboxes."""

from __future__ import annotations

import asyncio
import random

import anyio
import pytest

from btcap.actors import (
    Actor,
    ActorFailed,
    ActorSystem,
    Address,
    AskTimeout,
    DeadLetter,
    MailboxFull,
    Message,
    handler,
)

# -- messages -----------------------------------------------------------------------------


class Add(Message):
    k: int


class Get(Message):
    pass


class Ping(Message):
    n: int = 0


class Pong(Message):
    n: int = 0


class LoudPing(Ping):
    """A subclass message: dispatches to a ``Ping`` handler unless it has its own."""


class Shout(Message):
    text: str


class Step(Message):
    n: int


class SyncItem(Message):
    n: int


class AsyncItem(Message):
    n: int


class Item(Message):
    n: int


class Unknown(Message):
    pass


class Fail(Message):
    why: str


# -- actors -------------------------------------------------------------------------------


class Counter(Actor):
    def __init__(self) -> None:
        super().__init__()
        self.total = 0

    @handler
    def on_add(self, msg: Add) -> int:
        self.total += msg.k
        return self.total

    @handler
    def on_get(self, msg: Get) -> int:
        return self.total

    @handler
    def on_fail(self, msg: Fail) -> None:
        raise ValueError(msg.why)


class AsyncCounter(Actor):
    def __init__(self) -> None:
        super().__init__()
        self.total = 0

    @handler
    async def on_add(self, msg: Add) -> int:
        await asyncio.sleep(0)
        self.total += msg.k
        return self.total

    @handler
    async def on_fail(self, msg: Fail) -> None:
        await asyncio.sleep(0)
        raise ValueError(msg.why)


class Dispatch(Actor):
    """One handler per declaration style."""

    @handler(Ping, Pong)
    def on_ping_or_pong(self, msg: Ping | Pong) -> str:
        return f"decorated:{type(msg).__name__}"

    @handler
    def on_shout(self, msg: Shout | Get) -> str:
        return f"union:{type(msg).__name__}"

    @handler
    async def on_add(self, msg: Add) -> str:
        return "async"


class SpecialDispatch(Dispatch):
    """Inherits every handler, adds a more specific one for the subclass message."""

    @handler
    def on_loud(self, msg: LoudPing) -> str:
        return "loud"


class Chain(Actor):
    """A sync handler that tells itself: the follow-up must queue, never re-enter."""

    def __init__(self) -> None:
        super().__init__()
        self.log: list[str] = []
        self.finished = asyncio.Event()

    @handler
    def on_step(self, msg: Step) -> None:
        self.log.append(f"start {msg.n}")
        if msg.n < 3:
            self.ref.tell(Step(msg.n + 1))
        else:
            self.finished.set()
        self.log.append(f"end {msg.n}")

    @handler
    def on_get(self, msg: Get) -> list[str]:
        return list(self.log)


class Mixed(Actor):
    """Sync and async handlers; records order and how many handlers ran at once."""

    def __init__(self) -> None:
        super().__init__()
        self.seen: list[int] = []
        self.active = 0
        self.max_active = 0
        self.sync_during_async = 0

    @handler
    def on_sync(self, msg: SyncItem) -> int:
        if self.active:
            self.sync_during_async += 1
        self.seen.append(msg.n)
        return msg.n

    @handler
    async def on_async(self, msg: AsyncItem) -> int:
        self.active += 1
        self.max_active = max(self.max_active, self.active)
        await asyncio.sleep(0)
        if msg.n % 3 == 0:
            await asyncio.sleep(0.001)
        self.seen.append(msg.n)
        self.active -= 1
        return msg.n

    @handler
    def on_get(self, msg: Get) -> list[int]:
        return list(self.seen)


class Sender(Actor):
    """Forwards a burst to ``target`` from inside its own handler."""

    def __init__(self, target: Actor, kinds: list[bool]) -> None:
        super().__init__()
        self.target = target
        self.kinds = kinds

    @handler
    def on_ping(self, msg: Ping) -> None:
        ref = self.target.ref
        for n, is_sync in enumerate(self.kinds):
            ref.tell(SyncItem(n) if is_sync else AsyncItem(n), sender=self.address)


class Gate(Actor):
    """An async handler that waits until the test opens the gate."""

    def __init__(self) -> None:
        super().__init__()
        self.opened = asyncio.Event()
        self.done: list[int] = []

    @handler
    async def on_item(self, msg: Item) -> int:
        await self.opened.wait()
        self.done.append(msg.n)
        return msg.n


class NoAnnotation(Actor):
    @handler
    def on_anything(self, msg):  # type: ignore[no-untyped-def]
        return None


# -- helpers ------------------------------------------------------------------------------


def mixed_kinds(n: int, seed: int) -> list[bool]:
    """A reproducible random mix of sync (True) and async (False) messages."""
    rng = random.Random(seed)
    return [rng.random() < 0.5 for _ in range(n)]


# -- the local fast path ------------------------------------------------------------------


async def test_sync_handler_of_idle_actor_runs_inside_tell() -> None:
    with anyio.fail_after(5):
        async with ActorSystem("s") as system:
            counter = Counter()
            ref = system.spawn(counter, "counter")
            ref.tell(Add(2))
            assert counter.total == 2  # no await in between: handled inside tell
            system.tell(ref.address, Add(3))
            assert counter.total == 5
            system.ref("s/counter").tell(Add(4))
            assert counter.total == 9


async def test_sync_ask_of_idle_actor_does_not_yield_to_the_loop() -> None:
    with anyio.fail_after(5):
        async with ActorSystem("s") as system:
            ref = system.spawn(Counter(), "counter")
            ran: list[int] = []
            asyncio.get_running_loop().call_soon(ran.append, 1)
            assert await ref.ask(Add(7)) == 7
            assert await system.ask(ref.address, Get()) == 7
            assert ran == []  # the loop never ran: no queue, no task switch
            await asyncio.sleep(0)
            assert ran == [1]


async def test_async_handler_is_queued_and_answers_ask() -> None:
    with anyio.fail_after(5):
        async with ActorSystem("s") as system:
            counter = AsyncCounter()
            ref = system.spawn(counter, "counter")
            ref.tell(Add(2))
            assert counter.total == 0  # async handlers always go through the mailbox
            assert await ref.ask(Add(3)) == 5
            assert counter.total == 5


# -- dispatch -----------------------------------------------------------------------------


async def test_handler_chosen_by_message_type() -> None:
    with anyio.fail_after(5):
        async with ActorSystem("s") as system:
            ref = system.spawn(Dispatch(), "d")
            assert await ref.ask(Ping()) == "decorated:Ping"
            assert await ref.ask(Pong()) == "decorated:Pong"
            assert await ref.ask(Shout("hi")) == "union:Shout"
            assert await ref.ask(Get()) == "union:Get"
            assert await ref.ask(Add(1)) == "async"
            # A subclass message falls back to the handler of its base class ...
            assert await ref.ask(LoudPing()) == "decorated:LoudPing"
            # ... unless the actor has a handler for the subclass itself.
            special = system.spawn(SpecialDispatch(), "special")
            assert await special.ask(LoudPing()) == "loud"
            assert await special.ask(Ping()) == "decorated:Ping"  # inherited
            assert await ref.ask(LoudPing()) == "decorated:LoudPing"  # tables are per class


async def test_unhandled_message_fails_ask_and_is_counted_for_tell() -> None:
    with anyio.fail_after(5):
        async with ActorSystem("s") as system:
            ref = system.spawn(Counter(), "counter")
            with pytest.raises(ActorFailed) as err:
                await ref.ask(Unknown())
            assert err.value.error_type == "UnhandledMessage"
            assert err.value.detail == "Unknown"
            assert err.value.address == "s/counter"
            ref.tell(Unknown())
            assert system.stats.dropped == {"unhandled": 2}
            assert await ref.ask(Add(1)) == 1  # the actor is unharmed


async def test_handler_without_type_is_rejected_with_a_clear_error() -> None:
    with anyio.fail_after(5):
        async with ActorSystem("s") as system:
            ref = system.spawn(NoAnnotation(), "x")
            with pytest.raises(TypeError, match=r"NoAnnotation\.on_anything: annotate"):
                await ref.ask(Ping())


# -- typed replies, failures, timeouts, dead letters --------------------------------------


async def test_ask_checks_the_expected_reply_type() -> None:
    with anyio.fail_after(5):
        async with ActorSystem("s") as system:
            ref = system.spawn(Counter(), "counter")
            total: int = await ref.ask(Add(4), expect=int)
            assert total == 4
            with pytest.raises(TypeError, match="expected str, got int"):
                await ref.ask(Get(), expect=str)
            slow = system.spawn(AsyncCounter(), "slow")
            with pytest.raises(TypeError, match="expected Pong, got int"):
                await slow.ask(Add(1), expect=Pong)


@pytest.mark.parametrize("actor_type", [Counter, AsyncCounter])
async def test_ask_whose_handler_raised_gets_actor_failed(actor_type: type[Actor]) -> None:
    with anyio.fail_after(5):
        async with ActorSystem("s") as system:
            ref = system.spawn(actor_type(), "c")
            with pytest.raises(ActorFailed) as err:
                await ref.ask(Fail("bad input"))
            assert err.value.error_type == "ValueError"
            assert err.value.detail == "bad input"
            assert err.value.address == "s/c"
            assert "bad input" in str(err.value)


async def test_ask_timeout_raises_ask_timeout_and_the_late_reply_is_harmless() -> None:
    with anyio.fail_after(5):
        async with ActorSystem("s", ask_timeout=0.02) as system:
            gate = Gate()
            ref = system.spawn(gate, "gate")
            with pytest.raises(AskTimeout, match="no reply from s/gate to Item"):
                await ref.ask(Item(1), timeout=0.02)
            with pytest.raises(TimeoutError):  # the system default applies without timeout=
                await ref.ask(Item(2))
            gate.opened.set()
            assert await ref.ask(Item(3), timeout=1) == 3
            assert gate.done == [1, 2, 3]  # late replies went nowhere, harmlessly


async def test_ask_to_unknown_address_raises_dead_letter() -> None:
    with anyio.fail_after(5):
        async with ActorSystem("s") as system:
            with pytest.raises(DeadLetter, match="s/nobody"):
                await system.ref("s/nobody").ask(Ping())
            with pytest.raises(DeadLetter):
                await system.ask(Address("s", "nobody"), Ping())
            with pytest.raises(DeadLetter, match="no transport"):
                await system.ref("elsewhere/x").ask(Ping())
            assert system.stats.dead_letters == 2  # the local misses


async def test_tell_to_unknown_address_is_counted_and_never_raises() -> None:
    with anyio.fail_after(5):
        async with ActorSystem("s") as system:
            system.ref("s/nobody").tell(Ping())
            system.tell(Address("s", "ghost"), Ping())
            system.ref("other-system/x").tell(Ping())  # no transport: also a dead letter
            assert system.stats.dead_letters == 3
            ref = system.spawn(Counter(), "gone")
            system.stop(ref)
            ref.tell(Add(1))  # a stopped actor is a dead letter too
            assert system.stats.dead_letters == 4


# -- ordering and exclusivity -------------------------------------------------------------


async def test_messages_to_a_busy_actor_queue_instead_of_reentering() -> None:
    with anyio.fail_after(5):
        async with ActorSystem("s") as system:
            chain = Chain()
            ref = system.spawn(chain, "chain")
            ref.tell(Step(0))
            assert chain.log == ["start 0", "end 0"]  # the self-tell waits its turn
            # FIFO: Get is queued behind Step(1) but ahead of the Step(2) that Step(1) sends.
            assert await ref.ask(Get()) == ["start 0", "end 0", "start 1", "end 1"]
            await chain.finished.wait()
            assert chain.log == [f"{edge} {n}" for n in range(4) for edge in ("start", "end")]


@pytest.mark.parametrize("seed", [1, 2, 3])
async def test_order_and_exclusivity_across_sync_and_async_handlers(seed: int) -> None:
    kinds = mixed_kinds(60, seed)
    with anyio.fail_after(5):
        async with ActorSystem("s") as system:
            mixed = Mixed()
            ref = system.spawn(mixed, "mixed")
            for n, is_sync in enumerate(kinds):
                ref.tell(SyncItem(n) if is_sync else AsyncItem(n))
            assert await ref.ask(Get()) == list(range(len(kinds)))
            assert mixed.max_active == 1
            assert mixed.sync_during_async == 0


async def test_order_from_another_actor_across_sync_and_async_handlers() -> None:
    kinds = mixed_kinds(60, 11)
    with anyio.fail_after(5):
        async with ActorSystem("s") as system:
            mixed = Mixed()
            system.spawn(mixed, "mixed")
            sender = system.spawn(Sender(mixed, kinds), "sender")
            sender.tell(Ping())
            assert await mixed.ref.ask(Get()) == list(range(len(kinds)))
            assert mixed.max_active == 1
            assert mixed.sync_during_async == 0


async def test_concurrent_askers_never_overlap_handlers() -> None:
    with anyio.fail_after(5):
        async with ActorSystem("s") as system:
            mixed = Mixed()
            ref = system.spawn(mixed, "mixed")

            async def ask(n: int) -> int:
                msg = SyncItem(n) if n % 2 else AsyncItem(n)
                result: int = await ref.ask(msg, expect=int)
                return result

            results = await asyncio.gather(*(ask(n) for n in range(40)))
            assert results == list(range(40))
            assert sorted(mixed.seen) == list(range(40))
            assert mixed.max_active == 1
            assert mixed.sync_during_async == 0


# -- bounded mailbox ----------------------------------------------------------------------


async def test_full_mailbox_drops_tells_and_fails_asks() -> None:
    with anyio.fail_after(5):
        async with ActorSystem("s", mailbox_size=2) as system:
            gate = Gate()
            ref = system.spawn(gate, "gate")
            ref.tell(Item(1))
            ref.tell(Item(2))
            ref.tell(Item(3))  # no room: dropped, not raised
            assert system.stats.dropped == {"mailbox_full": 1}
            with pytest.raises(MailboxFull, match="s/gate"):
                await ref.ask(Item(4))
            assert system.stats.dropped == {"mailbox_full": 2}
            gate.opened.set()
            await asyncio.sleep(0)  # the drain runs once, handling both queued items
            assert gate.done == [1, 2]
            assert await ref.ask(Item(5)) == 5
            assert gate.done == [1, 2, 5]
