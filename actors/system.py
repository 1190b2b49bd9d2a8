"""The actor system: spawns actors inside the caller's event loop and routes their mail."""

from __future__ import annotations

import asyncio
import itertools
import math
import time
import uuid
from collections.abc import Coroutine
from functools import partial
from types import TracebackType
from typing import Any, TypeVar

import anyio
from anyio.abc import TaskGroup

from btcap.actors.cell import ActorCell
from btcap.actors.clock import Clock, TimeSource
from btcap.actors.errors import ActorError, DeadLetter, SystemClosed
from btcap.actors.failure import Failure, error_of, failure_of, runtime_messages
from btcap.actors.ref import ActorRef
from btcap.actors.refusals import Refusals
from btcap.actors.services import Services
from btcap.actors.stats import SystemStats
from btcap.actors.timers import (
    AskDeadlines,
    Expired,
    arm_timer,
    future_reply,
    on_the_wall,
    relay_reply,
    timed_out,
)
from btcap.transports.base import BROADCAST, Transport
from btcap.transports.codec import CodecError, Envelope, Kind
from btcap.transports.log import get_logger, worth_logging
from btcap.transports.message import Address, Message, MessageRegistry

# Failure and runtime_messages live in btcap.actors.failure; still importable from here.
__all__ = ["ActorSystem", "Failure", "runtime_messages"]

log = get_logger(__name__)

A = TypeVar("A", bound=ActorCell)
# Kind's members as constants: on 3.11 ``Kind.X`` goes through EnumType's attribute hook.
_TELL, _ASK, _REPLY, _FAIL = Kind.TELL, Kind.ASK, Kind.REPLY, Kind.FAIL


class ActorSystem:
    """Hosts actors in the running event loop; use as ``async with ActorSystem(...)``.

    Leaving the block stops every actor, cancels every task the system started, fails
    pending asks with :class:`SystemClosed` and closes the transport.
    """

    def __init__(
        self,
        system_id: str | None = None,
        *,
        transport: Transport | None = None,
        registry: MessageRegistry | None = None,
        clock: TimeSource | None = None,
        mailbox_size: int = 10_000,
        ask_timeout: float = 5.0,
    ) -> None:
        if transport is not None and system_id is not None and transport.system_id != system_id:
            raise ValueError(
                f"system id {system_id!r} differs from the transport's {transport.system_id!r}"
            )
        self.id: str = system_id or (transport.system_id if transport else uuid.uuid4().hex[:8])
        if "/" in self.id or self.id == BROADCAST:
            raise ValueError(f"system id {self.id!r} may not contain '/' or be '*'")
        self.transport = transport
        self.registry = registry if registry is not None else MessageRegistry()
        self.registry.register(Failure)
        self.clock: TimeSource = clock if clock is not None else Clock()
        self.mailbox_size = mailbox_size
        self.ask_timeout = ask_timeout
        self.stats = SystemStats()
        self.services = Services()  # what its parts share (e.g. a robot's mission control)
        self.address = Address(self.id, "$system")
        self._actors: dict[str, ActorCell] = {}
        self._names = itertools.count(1)
        self._corr = itertools.count(1)
        # corr -> (peer, reply, deadline on time.monotonic: inf off the wall)
        self._pending: dict[int, tuple[str, asyncio.Future[Any], float]] = {}
        self._deadlines = AskDeadlines(self._pending)
        self._wall = on_the_wall(self.clock)  # asks time out on the wall: see AskDeadlines
        self._tasks: set[asyncio.Task[Any]] = set()
        self._tg: TaskGroup | None = None
        self._closing = False
        self._failure: tuple[Address, BaseException] | None = None
        self._log = log.bind(system=self.id)
        self._refusals = Refusals(self.id, self._log)

    # -- lifecycle --------------------------------------------------------------------
    async def __aenter__(self) -> ActorSystem:
        if self._tg is not None:
            raise RuntimeError(f"actor system {self.id} is already running")
        self._tg = anyio.create_task_group()
        await self._tg.__aenter__()
        if self.transport is not None:
            try:
                await self._tg.start(self._serve_transport)
            except BaseException:
                await self._tg.__aexit__(None, None, None)
                raise
        return self

    async def _serve_transport(self, *, task_status: anyio.abc.TaskStatus[None]) -> None:
        assert self.transport is not None
        await self.transport.serve(self._on_envelope, task_status=task_status)

    async def __aexit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> bool | None:
        # Shielded: an escalation has already cancelled the scope this task runs in.
        with anyio.CancelScope(shield=True):
            await self.aclose()
        assert self._tg is not None
        self._tg.cancel_scope.cancel()
        tg, self._tg = self._tg, None
        if isinstance(exc, Exception):
            # The body's own error propagates as it is, not wrapped in an ExceptionGroup by
            # the task group (which holds nothing but the transport's receive loop).
            await tg.__aexit__(None, None, None)
            return None
        suppress = await tg.__aexit__(exc_type, exc, tb)
        # ``suppress`` means the exception was the cancellation an escalation caused.
        if self._failure is not None and (exc is None or suppress):
            where, err = self._failure
            raise ActorError(f"actor {where} escalated a failure to the system") from err
        return suppress

    async def aclose(self) -> None:
        """Stop every actor and task; safe to call more than once."""
        if self._closing:
            return
        self._closing = True
        for actor in sorted(self._actors.values(), key=lambda a: -len(a.address.path)):
            self.stop(actor)
        tasks = list(self._tasks)
        for task in tasks:
            task.cancel()
        if tasks:
            await asyncio.gather(*tasks, return_exceptions=True)
        pending = list(self._pending.values())
        self._pending.clear()
        self._deadlines.cancel()
        for _peer, fut, _deadline in pending:
            if not fut.done():
                fut.set_exception(SystemClosed(f"actor system {self.id} shut down"))

    @property
    def running(self) -> bool:
        return self._tg is not None and not self._closing

    @property
    def pending_asks(self) -> int:
        """Asks awaiting a reply (a bounded table: the simulation test checks it)."""
        return len(self._pending)

    def start_task(
        self, coro: Coroutine[Any, Any, Any], *, name: str | None = None
    ) -> asyncio.Task[Any]:
        """A task of the running system, cancelled and awaited when it closes (not a task
        group's: one failure must not cancel its siblings, and callers read its error)."""
        if self._tg is None or self._closing:
            coro.close()
            raise SystemClosed(f"actor system {self.id} is not running")
        task = asyncio.get_running_loop().create_task(coro, name=name)
        self._tasks.add(task)
        task.add_done_callback(self._task_done)
        return task

    def _task_done(self, task: asyncio.Task[Any]) -> None:
        self._tasks.discard(task)
        if not task.cancelled() and (exc := task.exception()) is not None:
            self._log.error("actors.task_failed", task=task.get_name(), exc_info=exc)

    # -- actors -----------------------------------------------------------------------
    def spawn(
        self, actor: A, name: str | None = None, *, parent: ActorCell | None = None
    ) -> ActorRef[A]:
        """Give ``actor`` an address in this system and start it."""
        if actor._system is not None:
            raise ValueError(f"{type(actor).__name__} is already spawned at {actor._address}")
        if self._closing:
            raise SystemClosed(f"actor system {self.id} is shutting down")
        if name is None:
            name = f"{type(actor).__name__.lower()}-{next(self._names)}"
        elif not name or "/" in name:
            raise ValueError(f"actor name {name!r}: expected a non-empty name without '/'")
        if parent is not None and parent._system is not self:
            raise ValueError("the parent must be spawned in the same system")
        path = name if parent is None else f"{parent.address.path}/{name}"
        if path in self._actors:
            raise ValueError(f"an actor already lives at {self.id}/{path}")
        actor._system = self
        actor._address = Address(self.id, path)
        actor._parent = parent
        self._actors[path] = actor
        try:
            actor.on_start()
        except BaseException:
            self.stop(actor)
            raise
        return ActorRef(actor._address, self, actor)

    def stop(self, target: ActorCell | ActorRef[Any]) -> None:
        """Stop an actor and its children; queued asks fail with :class:`DeadLetter`."""
        actor = target._local if isinstance(target, ActorRef) else target
        if actor is None or actor._system is not self:
            return
        prefix = actor.address.path + "/"
        for path in [p for p in self._actors if p.startswith(prefix)]:
            child = self._actors.get(path)
            if child is not None:
                self.stop(child)
        self._actors.pop(actor.address.path, None)
        try:
            actor.on_stop()
        except Exception as exc:
            self._log.error("actor.on_stop_failed", actor=str(actor.address), exc_info=exc)
        actor._system = None
        box, actor._mailbox = actor._mailbox, None
        if box:
            gone: ActorError = (
                SystemClosed(f"actor system {self.id} shut down")
                if self._closing
                else DeadLetter(f"{actor.address} was stopped")
            )
            for _msg, reply, _sender in box:
                if reply is not None:
                    reply(None, gone)
        if actor._tasks:
            for task in list(actor._tasks):
                task.cancel()

    def lookup(self, path: str) -> ActorCell | None:
        return self._actors.get(path)

    def ref(self, address: Address | str) -> ActorRef[Any]:
        """A handle to any actor, here or on a peer system."""
        if isinstance(address, str):
            address = Address.parse(address) if "/" in address else Address(self.id, address)
        local = self._actors.get(address.path) if address.system == self.id else None
        return ActorRef(address, self, local)

    def __len__(self) -> int:
        return len(self._actors)

    # -- messaging --------------------------------------------------------------------
    def tell(self, address: Address, msg: Any, *, sender: Address | None = None) -> None:
        if address.system == self.id:
            actor = self._actors.get(address.path)
            if actor is None:
                self._dead_letter(address, msg)
            else:
                actor._receive(msg, None)
        else:
            self._send(Envelope(_TELL, sender or self.address, address, msg))

    def broadcast(self, path: str, msg: Message, *, include_self: bool = False) -> None:
        """Send to the actor at ``path`` on every peer system."""
        if self.transport is not None:
            self._send(Envelope(_TELL, self.address, Address(BROADCAST, path), msg))
        if include_self:
            self.tell(Address(self.id, path), msg)

    async def ask(self, address: Address, msg: Any, *, timeout: float | None = None) -> Any:
        """Request/response to any address; see :meth:`ActorRef.ask`."""
        if self._closing:
            raise SystemClosed(f"actor system {self.id} is shutting down")
        # The C Future on the running loop: loop.create_future() is a Python call more.
        fut: asyncio.Future[Any] = asyncio.Future()
        if address.system == self.id:
            actor = self._actors.get(address.path)
            if actor is None:
                self._dead_letter(address, msg)
                raise DeadLetter(f"no actor at {address}")
            if actor._can_call_now(msg):
                result = actor._call_now(msg)
                if isinstance(result, asyncio.Future):
                    return await self.await_deferred(address, msg, result, timeout)
                return result
            actor._receive(msg, future_reply(fut))
        else:
            transport = self.transport
            if transport is None:
                raise DeadLetter(f"no transport to reach {address}")
            limit = self.ask_timeout if timeout is None else timeout
            corr = next(self._corr)
            # On the wall no timer of its own, one for every pending ask (AskDeadlines).
            timer = None if self._wall else arm_timer(self.clock, limit, fut)
            deadline = time.monotonic() + limit if timer is None else math.inf
            self._pending[corr] = (address.system, fut, deadline)
            if deadline < self._deadlines.at:  # else armed soon enough: no call
                self._deadlines.arm(deadline)
            try:
                transport.send(Envelope(_ASK, self.address, address, msg, corr))
                return await fut
            except Expired:
                raise timed_out(address, msg, limit) from None
            finally:
                self._pending.pop(corr, None)
                if timer is not None:
                    timer.cancel()
        return await self._reply_within(fut, timeout, address, msg)

    async def await_deferred(
        self, address: Address, msg: Any, fut: asyncio.Future[Any], timeout: float | None
    ) -> Any:
        """Wait for a reply a handler deferred by returning a Future (fast-path asks)."""
        # Our own future to time out: the handler's must stay free for its late answer.
        waiter: asyncio.Future[Any] = asyncio.get_running_loop().create_future()
        relay = partial(relay_reply, waiter)
        fut.add_done_callback(relay)
        try:
            return await self._reply_within(waiter, timeout, address, msg)
        finally:
            fut.remove_done_callback(relay)

    async def _reply_within(
        self, fut: asyncio.Future[Any], timeout: float | None, address: Address, msg: Any
    ) -> Any:
        """``fut``'s result, or :class:`AskTimeout` once the ask's limit has passed."""
        limit = self.ask_timeout if timeout is None else timeout
        # One timer instead of a timeout context: an ask is a hot path.
        timer = arm_timer(self.clock, limit, fut)
        try:
            return await fut
        except Expired:
            raise timed_out(address, msg, limit) from None
        finally:
            timer.cancel()

    def _send(self, env: Envelope) -> None:
        if self.transport is None:
            return self._dead_letter(env.recipient, env.msg)
        self.transport.send(env)

    def _on_envelope(self, env: Envelope) -> None:
        """Entry point for everything a transport received."""
        kind = env.kind
        if kind is _REPLY or kind is _FAIL:
            pending = self._pending.get(env.corr)
            # Only the system that was asked may answer: correlation ids are guessable.
            if pending is None or pending[0] != env.sender.system or pending[1].done():
                self._count_drop("late_reply", env.sender, env.msg)
                return
            del self._pending[env.corr]
            fut = pending[1]
            if kind is _FAIL:
                fut.set_exception(error_of(env.sender, env.msg))
            else:
                fut.set_result(env.msg)
            return
        if env.recipient.system != self.id and env.recipient.system != BROADCAST:
            self._count_drop("wrong_recipient", env.recipient, env.msg)
            return
        actor = self._actors.get(env.recipient.path)
        if actor is None:
            if env.recipient.system == BROADCAST:
                # A broadcast reaches systems that do not host that service: not an error.
                self.stats.dropped["broadcast_unhandled"] = (
                    self.stats.dropped.get("broadcast_unhandled", 0) + 1
                )
                return
            self._dead_letter(env.recipient, env.msg, origin=env.sender)
            if kind is _ASK:
                self._reply_remote(
                    env, None, DeadLetter(f"no actor at {self.id}/{env.recipient.path}")
                )
            return
        h = actor._handlers.get(type(env.msg)) if actor._handlers else None  # a call less
        h = h or actor._handler_for(type(env.msg))
        if h is not None and h.local_only:  # whatever sender it names: it came from outside
            self._refusals.refuse(env, self.stats.refused, self._reply_remote)
            return
        reply = partial(self._reply_remote, env) if kind is _ASK else None
        actor._receive(env.msg, reply, env.sender.system, h)

    def _reply_remote(self, env: Envelope, result: Any, error: BaseException | None) -> None:
        to = env.recipient  # a broadcast's reply names us, not "*":
        me = to if to.system == self.id else Address(self.id, to.path)
        if error is None and result is not None and not isinstance(result, Message):
            error = TypeError(f"reply of type {type(result).__qualname__} is not a Message")
        if error is None:
            try:  # the transport's own send, not _send(): one call less on the hot path
                send = self._send if self.transport is None else self.transport.send
                send(Envelope(_REPLY, me, env.sender, result, env.corr))
                return
            except CodecError as exc:  # e.g. an unregistered reply type
                error = exc
        failure = failure_of(error)
        try:
            self._send(Envelope(_FAIL, me, env.sender, failure, env.corr))
        except CodecError:
            # The transport's codec does not know Failure (see runtime_messages()).
            self._count_drop("reply_unencodable", env.sender, failure)

    # -- accounting -------------------------------------------------------------------
    # A peer can send any number of these: each is counted, and logged only while
    # worth_logging says so, so a flood costs a counter, not a flood of lines.
    def _dead_letter(self, address: Address, msg: Any, *, origin: Address | None = None) -> None:
        n = self.stats.dead_letters = self.stats.dead_letters + 1
        if worth_logging(n):
            self._log.info(
                "actors.dead_letter",
                to=str(address),
                message=type(msg).__qualname__,
                origin=str(origin) if origin else None,
                count=n,
            )

    def _count_drop(self, reason: str, address: Address | None, msg: Any) -> None:
        n = self.stats.dropped[reason] = self.stats.dropped.get(reason, 0) + 1
        if worth_logging(n):
            # A reply after its ask timed out or was cancelled is routine, not a fault.
            emit = self._log.info if reason == "late_reply" else self._log.warning
            emit(
                "actors.dropped",
                reason=reason,
                to=str(address),
                message=type(msg).__qualname__,
                count=n,
            )

    def _count_failure(self, kind: str) -> int:
        n = self.stats.failures[kind] = self.stats.failures.get(kind, 0) + 1
        return n

    def _escalated(self, where: Address | None, exc: BaseException) -> None:
        self.stats.escalations += 1
        if self._failure is None and where is not None:
            self._failure = (where, exc)
        if self._tg is not None:
            self._tg.cancel_scope.cancel()
