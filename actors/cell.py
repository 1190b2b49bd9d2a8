"""The runtime side of an actor: handler tables, mailbox, the direct-call fast path, supervision.

:class:`ActorCell` knows its system only through :class:`Host`, the few things a cell needs
from it, so this module sits below ``ref`` and ``system``; the user-facing
:class:`~btcap.actors.actor.Actor` adds the typed ``system`` and ``ref`` above them.
"""

from __future__ import annotations

import asyncio
import enum
import typing
from collections import deque
from collections.abc import Awaitable, Callable, Coroutine
from typing import Any, ClassVar, Protocol

from btcap._enum import FastEnumType
from btcap.actors.errors import ActorFailed, DeadLetter, MailboxFull, SystemClosed
from btcap.actors.handlers import Handler, collect_handlers, handler
from btcap.transports.log import get_logger, worth_logging
from btcap.transports.message import Address

# handler lives in btcap.actors.handlers; still importable from here.
__all__ = ["ActorCell", "Host", "Reply", "Supervision", "handler"]

log = get_logger(__name__)

#: Called once with the handler's result, or with the error that replaces it.
Reply = Callable[[Any, BaseException | None], None]


class Supervision(enum.Enum, metaclass=FastEnumType):
    """What happens to an actor whose handler raised.

    RESUME keeps its state and goes on; RESTART calls :meth:`Actor.on_restart` (up to
    ``max_restarts`` times, then stops it); STOP stops it; ESCALATE stops it and fails
    its parent the same way (or the whole system, for a top-level actor).
    """

    RESUME = "resume"
    RESTART = "restart"
    STOP = "stop"
    ESCALATE = "escalate"


def _reply(reply: Reply, result: Any) -> None:
    """Answer an ask; a Future result is a deferred reply, sent when it resolves.

    Handlers return a Future to answer later (a motion that ends in a minute) without
    keeping the actor busy meanwhile.
    """
    if isinstance(result, asyncio.Future):
        result.add_done_callback(lambda f: _settle(reply, f))
    else:
        reply(result, None)


def _settle(reply: Reply, fut: asyncio.Future[Any]) -> None:
    if fut.cancelled():
        reply(None, ActorFailed("?", "Cancelled", "the deferred reply was cancelled"))
    elif (exc := fut.exception()) is not None:
        reply(None, exc)
    else:
        reply(fut.result(), None)


_RUNTIME_NAMES = frozenset(
    [
        "_as_failure",
        "_call_now",
        "_can_call_now",
        "_drain",
        "_enqueue",
        "_failed",
        "_handler_for",
        "_live_host",
        "_receive",
        "_schedule_drain",
        "_unhandled",
    ]
)
"""The runtime's own methods of a cell: an actor class that defines one is refused."""


class Host(Protocol):
    """What a cell and a ref need from the system they live in (``ActorSystem`` is one).

    The underscored members are the runtime's own contract between a cell and its system.
    """

    id: str
    mailbox_size: int
    _closing: bool

    def start_task(
        self, coro: Coroutine[Any, Any, Any], *, name: str | None = None
    ) -> asyncio.Task[Any]: ...

    def stop(self, target: ActorCell) -> None: ...

    def tell(self, address: Address, msg: Any, *, sender: Address | None = None) -> None: ...

    async def ask(self, address: Address, msg: Any, *, timeout: float | None = None) -> Any: ...

    async def await_deferred(
        self, address: Address, msg: Any, fut: asyncio.Future[Any], timeout: float | None
    ) -> Any: ...

    def _count_drop(self, reason: str, address: Address | None, msg: Any) -> None: ...

    def _count_failure(self, kind: str) -> int: ...

    def _escalated(self, where: Address | None, exc: BaseException) -> None: ...


class ActorCell:
    """The runtime state and delivery of an actor; subclass :class:`Actor`, not this.

    A cell handles one message at a time, in arrival order per sender. When it is idle,
    a local sender's message is handled by a direct call (no queue, no task switch); when
    it is busy, or the handler is async, the message waits in a bounded mailbox drained by
    a task of the system. A handler may return an ``asyncio.Future`` to reply later.
    """

    __slots__ = (
        "_address",
        "_busy",
        "_mailbox",
        "_parent",
        "_restarts",
        "_sender",
        "_system",
        "_tasks",
    )

    supervision: ClassVar[Supervision] = Supervision.RESTART
    max_restarts: ClassVar[int] = 10
    _handlers: ClassVar[dict[type[Any], Handler] | None] = None

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        cls._handlers = None  # built on first message, when forward references resolve
        clash = _RUNTIME_NAMES & cls.__dict__.keys()
        if clash:
            raise TypeError(
                f"{cls.__qualname__} overrides the actor runtime's own "
                f"{', '.join(sorted(clash))}; choose other names"
            )

    def __init__(self) -> None:
        self._system: Host | None = None
        self._address: Address | None = None
        self._busy = False
        self._mailbox: deque[tuple[Any, Reply | None, str | None]] | None = None
        self._sender: str | None = None
        self._parent: ActorCell | None = None
        self._restarts = 0
        self._tasks: set[asyncio.Task[Any]] | None = None

    # -- identity -------------------------------------------------------------------
    @property
    def sender(self) -> str:
        """The system the message being handled came from, as its transport authenticated
        it (not what the message says about itself); this system's id for local mail."""
        sender = self._sender
        return self._live_host().id if sender is None else sender

    @property
    def address(self) -> Address:
        if self._address is None:
            raise RuntimeError(f"{type(self).__name__} is not spawned in an actor system")
        return self._address

    @property
    def spawned(self) -> bool:
        return self._system is not None

    def _live_host(self) -> Host:
        if self._system is None:
            raise RuntimeError(f"{type(self).__name__} is not spawned in an actor system")
        return self._system

    @property
    def parent(self) -> ActorCell | None:
        return self._parent

    # -- hooks ----------------------------------------------------------------------
    def on_start(self) -> None:
        """Called when spawned; start background tasks here."""

    def on_stop(self) -> None:
        """Called once when stopped; its own tasks are cancelled right after."""

    def on_restart(self, error: BaseException) -> None:
        """Called under the RESTART policy after a handler raised: reset state here."""

    # -- background work --------------------------------------------------------------
    def start_task(
        self, coro: Coroutine[Any, Any, Any], *, name: str | None = None
    ) -> asyncio.Task[Any]:
        """Run ``coro`` as a task owned by this actor: cancelled when the actor stops."""
        task = self._live_host().start_task(coro, name=name or f"{self.address}")
        if self._tasks is None:
            self._tasks = set()
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)
        return task

    # -- delivery -------------------------------------------------------------------
    @classmethod
    def _handler_for(cls, t: type[Any]) -> Handler | None:
        table = cls._handlers
        if table is None:
            table = cls._handlers = collect_handlers(cls)
        h = table.get(t)
        if h is None:
            for base in t.__mro__[1:]:
                h = table.get(base)
                if h is not None:
                    table[t] = h
                    break
        return h

    def _receive(
        self, msg: Any, reply: Reply | None, sender: str | None = None, h: Handler | None = None
    ) -> None:
        """Deliver a message: handle it now if idle and sync, else queue it.

        ``sender`` is the system the transport authenticated (None: this system); ``h``
        the handler of ``msg``'s type if the caller looked it up already.
        """
        if self._busy or self._mailbox:
            self._enqueue(msg, reply, sender)
            return
        if h is None:
            h = self._handler_for(type(msg))
        if h is None:
            self._unhandled(msg, reply)
            return
        if h.is_async:
            self._enqueue(msg, reply, sender)
            return
        self._busy = True
        self._sender = sender
        try:
            result = h.fn(self, msg)
        except Exception as exc:
            self._busy = False
            self._failed(exc, msg, reply)
        else:
            self._busy = False
            if reply is not None:
                if isinstance(result, asyncio.Future):
                    _reply(reply, result)
                else:  # _reply() inlined: the hot path of a remote ask
                    reply(result, None)
        if self._mailbox and self._system is not None:
            self._schedule_drain()

    def _call_now(self, msg: Any) -> Any:
        """The ask fast path: the caller checked the actor is idle and the handler sync."""
        h = self._handler_for(type(msg))
        if h is None:
            err = self._unhandled(msg, None)
            raise err
        self._busy = True
        self._sender = None
        try:
            return h.fn(self, msg)
        except Exception as exc:
            self._busy = False
            self._failed(exc, msg, None)
            raise self._as_failure(exc) from exc
        finally:
            self._busy = False
            if self._mailbox and self._system is not None:
                self._schedule_drain()

    def _can_call_now(self, msg: Any) -> bool:
        if self._busy or self._mailbox or self._system is None:
            return False
        h = self._handler_for(type(msg))
        return h is not None and not h.is_async

    def _enqueue(self, msg: Any, reply: Reply | None, sender: str | None = None) -> None:
        system = self._system
        if system is None:
            if reply is not None:
                reply(None, DeadLetter(f"{type(self).__name__} is stopped"))
            return
        box = self._mailbox
        if box is None:
            box = self._mailbox = deque()
        if len(box) >= system.mailbox_size:
            system._count_drop("mailbox_full", self._address, msg)
            if reply is not None:
                reply(None, MailboxFull(f"mailbox of {self._address} is full"))
            return
        box.append((msg, reply, sender))
        if not self._busy:
            self._schedule_drain()

    def _schedule_drain(self) -> None:
        system = self._live_host()
        if system._closing:
            return  # the closing system stops this actor, which fails what is queued
        self._busy = True
        system.start_task(self._drain(), name=f"drain {self._address}")

    async def _drain(self) -> None:
        box = self._mailbox
        try:
            while box and self._system is not None:
                msg, reply, self._sender = box.popleft()
                h = self._handler_for(type(msg))
                if h is None:
                    self._unhandled(msg, reply)
                    continue
                try:
                    result = h.fn(self, msg)
                    if h.is_async:
                        result = await typing.cast(Awaitable[Any], result)
                except asyncio.CancelledError:
                    # Only a closing system cancels a drain: never leave the asker hanging.
                    if reply is not None:
                        reply(
                            None,
                            SystemClosed(
                                f"{self._address} shut down while handling {type(msg).__qualname__}"
                            ),
                        )
                    raise
                except Exception as exc:
                    self._failed(exc, msg, reply)
                else:
                    if reply is not None:
                        _reply(reply, result)
        finally:
            self._busy = False

    def _unhandled(self, msg: Any, reply: Reply | None) -> ActorFailed:
        err = ActorFailed(str(self._address), "UnhandledMessage", type(msg).__qualname__)
        if self._system is not None:
            self._system._count_drop("unhandled", self._address, msg)
        if reply is not None:
            reply(None, err)
        return err

    def _as_failure(self, exc: BaseException) -> ActorFailed:
        return ActorFailed(str(self._address), type(exc).__qualname__, str(exc))

    def _failed(self, exc: Exception, msg: Any, reply: Reply | None) -> None:
        system = self._system
        policy = type(self).supervision
        kind = f"{type(self).__qualname__}: {type(msg).__qualname__}: {type(exc).__qualname__}"
        # The first failure of a kind carries its traceback; repeats (a peer sending the
        # same bad message again and again) are counted and get one rate-limited line.
        n = system._count_failure(kind) if system is not None else 1
        if worth_logging(n):
            log.error(
                "actor.handler_failed",
                system=system.id if system else None,
                actor=str(self._address),
                message=type(msg).__qualname__,
                policy=policy.value,
                sender=self._sender,
                count=n,
                **({"exc_info": exc} if n == 1 else {"error": str(exc)[:200]}),
            )
        if reply is not None:
            reply(None, self._as_failure(exc))
        if system is None:
            return
        if policy is Supervision.RESTART:
            self._restarts += 1
            if self._restarts > type(self).max_restarts:
                system.stop(self)
                return
            try:
                self.on_restart(exc)
            except Exception as again:
                log.error("actor.restart_failed", actor=str(self._address), exc_info=again)
                system.stop(self)
        elif policy is Supervision.STOP:
            system.stop(self)
        elif policy is Supervision.ESCALATE:
            parent = self._parent
            system.stop(self)
            if parent is not None and parent._system is not None:
                parent._failed(exc, msg, None)
            else:
                system._escalated(self._address, exc)
