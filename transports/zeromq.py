"""ZeroMQ transport: one ROUTER bound per system, one DEALER per peer.

Each message is one frame: ``M`` + a codec-encoded envelope, or ``H`` + the sender's
endpoint (a hello: a system that joins later is answered without configuring it). The
sender is the DEALER's routing id, with keys the member ZAP authenticated
(:mod:`~btcap.transports.security`). Anything else, a peer that never said hello, or an
envelope whose sender is not that peer is dropped, logged and counted.

Sockets are plain pyzmq ones: sends never block (``NOBLOCK``), and a reader callback on
the ROUTER's descriptor drains it and hands envelopes straight to the actor system (no
futures, no task switch per message). One frame per message, not two, saves a ``recv``,
a ``send`` and a ``RCVMORE`` query: most of what a round trip costs in Python.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
from typing import Any

import zmq
import zmq.asyncio
from anyio.abc import TaskStatus

from btcap.transports.base import BROADCAST, Deliver, Transport, TransportStats
from btcap.transports.bounds import MAX_DEPTH
from btcap.transports.codec import Codec, CodecError, Envelope
from btcap.transports.log import get_logger
from btcap.transports.message import MessageRegistry
from btcap.transports.newcomers import LINKS_PER_PEER
from btcap.transports.security import (
    DEFAULT_MAX_MESSAGE_BYTES,
    KeyPair,
    TeamKeys,
    authenticated,
    curve_for,
)
from btcap.transports.trust import DEFAULT_POLL_S, first_listing, watch_trusted
from btcap.transports.zmq_endpoints import (
    SCHEMES,
    check_id,
    check_newcomer_args,
    check_transport_args,
)
from btcap.transports.zmq_io import (
    EVENTS,
    NOBLOCK,
    POLLIN,
    Received,
    allow_sockets,
    fd_of,
    read_plain,
    read_secure,
    remove_ipc_file,
)
from btcap.transports.zmq_monitors import Monitor
from btcap.transports.zmq_peers import PeerBook, PeerFates
from btcap.transports.zmq_rules import HEAVY_BYTES as _HEAVY_BYTES
from btcap.transports.zmq_rules import PeerRules
from btcap.transports.zmq_sockets import (
    COPY_THRESHOLD,
    open_dealer,
    open_router,
    reject,
    send_frame,
    unsent,
    write,
)

__all__ = ["ZmqTransport"]

log = get_logger(__name__)

_MSG = b"M"
_HELLO = b"H"
_MSG_BYTE = _MSG[0]
_BATCH = 256
"""Messages handled per reader callback before other callbacks get a turn."""
_JUNK_COST = 31
"""More of that turn a malformed message takes: refusing junk can cost more than delivering
(a frame nested too deeply: ~0.2 ms), so a flood of it lets other callbacks in sooner."""
_HEAVY = _BATCH // _JUNK_COST + 1
"""What a message of over :data:`HEAVY_BYTES` costs: all of that turn."""


class ZmqTransport(PeerFates, PeerRules, Transport):
    """Reach peers over ``inproc://``, ``ipc://`` or ``tcp://``.

    ``bind`` may use port ``*``; :attr:`endpoint` then tells the port chosen. Bound to a
    wildcard address, pass ``advertise``: the endpoint sent in hellos. ``peers`` maps
    system ids to endpoints (more via :meth:`add_peer`); with ``accept_hello`` any system
    that says hello becomes a peer, up to ``max_peers``: a stranger (known only from its
    hello, or again since its link dropped) makes room for a newcomer and is dropped
    after ``stranger_ttl_s`` unless it speaks; at most ``max_strangers`` at once (see
    :mod:`~btcap.transports.zmq_peers`). A hello from a new endpoint (a restart
    elsewhere) reconnects there. :meth:`forget` drops a peer declared gone.
    ``inproc://`` only reaches transports on the same zmq context. Use a transport from
    the thread running its event loop.

    Security: ``keys`` (a :class:`KeyPair` or a secret certificate ``NAME.key_secret``)
    and ``trusted`` (a :class:`TeamKeys` or a directory of public certificates
    ``NAME.key``, this system's own included) go together: traffic is CURVE-encrypted,
    only allow-listed members complete a handshake, a peer is the member its key names,
    and only a member's hello opens a connection back (a ZAP handler in a zmq context of
    its own; ``inproc://`` is refused). Without keys it binds loopback/ipc/inproc only
    unless ``insecure=True``. ``max_message_bytes`` bounds a frame: libzmq cuts off a
    connection that sends a bigger one (see :attr:`disconnects`). Roles: PeerRules.
    A trusted folder is polled every ``trusted_poll_s`` seconds (0: never): a key removed
    from it is refused and its links closed (:mod:`~btcap.transports.trust`).
    Inbound connections: closed if silent ``hello_timeout_s``, ``max_newcomers`` silent at
    most, ``links_per_peer`` per peer (``newcomers``; :mod:`~btcap.transports.newcomers`).
    """

    def __init__(
        self,
        system_id: str,
        bind: str,
        registry: MessageRegistry,
        *,
        peers: dict[str, str] | None = None,
        accept_hello: bool = True,
        max_peers: int = 1024,
        advertise: str | None = None,
        context: zmq.Context[Any] | None = None,
        keys: KeyPair | str | os.PathLike[str] | None = None,
        trusted: TeamKeys | str | os.PathLike[str] | None = None,
        insecure: bool = False,
        max_message_bytes: int = DEFAULT_MAX_MESSAGE_BYTES,
        stranger_ttl_s: float = 30.0,
        max_strangers: int = 64,
        trusted_poll_s: float = DEFAULT_POLL_S,
        hello_timeout_s: float = 10.0,
        max_newcomers: int = 128,
        links_per_peer: int = LINKS_PER_PEER,
    ) -> None:
        check_transport_args(system_id, bind, advertise, max_message_bytes)
        self.newcomers = check_newcomer_args(hello_timeout_s, max_newcomers, links_per_peer)
        self._strangers = PeerBook(stranger_ttl_s, max_strangers, max_peers)
        self._first_listing = first_listing(trusted)  # before the keys load
        self.curve = curve_for(system_id, bind, keys, trusted, insecure)
        self.trusted_poll_s = trusted_poll_s
        self.max_message_bytes = max_message_bytes
        # Frames shorter than this are copied into zmq and within bounds: sent inline.
        self._small = min(COPY_THRESHOLD, max_message_bytes + 1)
        self.system_id = system_id
        self.stats = TransportStats()
        self.codec = Codec(registry)
        self.accept_hello = accept_hello
        self.max_peers = max_peers
        self._id = system_id.encode()
        self._own_ctx = self.curve is not None and context is None
        base = context if context is not None else zmq.asyncio.Context.instance()
        # Plain sockets on one context (inproc:// connects); our own reader callback.
        self._ctx: zmq.Context[zmq.Socket[bytes]] = (
            zmq.Context() if self._own_ctx else zmq.Context.shadow(base.underlying)
        )
        allow_sockets(self._ctx)
        try:
            self._router, self._events = open_router(
                self._ctx,
                bind,
                self.curve,
                max_message_bytes,
                self.stats,
                system_id,
                self.newcomers,
            )
        except ValueError:
            if self._own_ctx:
                self._ctx.term()
            raise
        bound = self._router.getsockopt_string(zmq.LAST_ENDPOINT)
        self._fd = fd_of(self._router)
        # Bound once, not per wake-up. ``get``, not ``getsockopt``: no enum of the answer.
        self._recv, self._get = self._router.recv, self._router.get
        self.endpoint: str = advertise or bound
        self.bound_endpoint: str = bound
        self._dealers: dict[str, zmq.Socket[bytes]] = {}
        self._endpoints: dict[str, str] = {}
        self._configured: set[str] = set()
        self._known: dict[bytes, str] = {}
        self._monitors: dict[str, Monitor] = {}
        self.hellos = 0
        self._init_rules()
        self._deliver: Deliver | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stopped: asyncio.Future[None] | None = None
        self._closed = False
        try:
            for sid, ep in (peers or {}).items():
                self.add_peer(sid, ep)
        except BaseException:
            self.close()
            raise

    @property
    def disconnects(self) -> int:
        """Inbound connections closed (by peers, libzmq or us), counted as libzmq reports them."""
        return self._events.disconnects

    # -- peers ------------------------------------------------------------------------
    def add_peer(self, system_id: str, endpoint: str) -> None:
        """Connect to a peer and say hello (idempotent; a new endpoint replaces the old)."""
        if (why := check_id(system_id)) is not None:
            raise ValueError(f"peer id {system_id!r}: {why}")
        self._connect(system_id, endpoint)
        self._configured.add(system_id)

    def _connect(self, system_id: str, endpoint: str) -> None:
        if self._closed:
            raise RuntimeError(f"transport of {self.system_id} is closed")
        if system_id == self.system_id or self._endpoints.get(system_id) == endpoint:
            return
        if not endpoint.startswith(SCHEMES):
            raise ValueError(f"peer {system_id}: endpoint {endpoint!r} is not tcp/ipc/inproc")
        sock, monitor = open_dealer(self._ctx, self._id, system_id, endpoint, self._events)
        self._unlink(system_id)  # a peer that moved stays configured, or a stranger
        self._dealers[system_id] = sock
        self._endpoints[system_id] = endpoint
        self._known[system_id.encode()] = system_id
        self._classify(system_id)
        # The first hello waits in the DEALER's queue until the connection is up.
        self._write(system_id, sock, _HELLO, self._hello())
        if monitor is not None:
            self._monitors[system_id] = monitor
            if self._loop is not None:
                self._watch(monitor)

    def remove_peer(self, system_id: str) -> None:
        """Forget a peer: messages to it become undeliverable, messages from it dropped."""
        self._unclassify(system_id)
        self._configured.discard(system_id)
        self._strangers.dropped(system_id)  # forgotten either way
        self._known.pop(system_id.encode(), None)
        self._claims.forget(system_id)
        self._unlink(system_id)
        if self._events.watch is not None and not self._closed:
            self._events.watch.dropped(system_id)  # its links must say hello again

    def _unlink(self, system_id: str) -> None:
        sock = self._dealers.pop(system_id, None)
        self._endpoints.pop(system_id, None)
        monitor = self._monitors.pop(system_id, None)
        if monitor is not None:
            if self._loop is not None and not self._loop.is_closed():
                self._loop.remove_reader(monitor.fd)
            monitor.close()
        if sock is not None:
            sock.close(0)

    # -- sending ----------------------------------------------------------------------
    def send(self, env: Envelope) -> None:
        frame = _MSG + self.codec.encode(env)
        target = env.recipient.system
        dealer = self._dealers.get(target)  # none for a broadcast: "*" is no peer id
        if dealer is not None and len(frame) < self._small:  # write() inlined: hot path
            try:
                send_frame(dealer, frame, NOBLOCK)
            except zmq.ZMQError as exc:
                unsent(self.stats, target, exc)
            else:
                self.stats.sent += 1
        elif target == BROADCAST:
            for sid, sock in list(self._dealers.items()):
                if sid not in self._observers:  # they ask; team news is not for them
                    write(sock, frame, self.max_message_bytes, self.stats, self.system_id, sid)
        elif dealer is None:
            self.stats.undeliverable += 1
            self.stats.drop(f"no peer {target}")
        else:
            write(dealer, frame, self.max_message_bytes, self.stats, self.system_id, target)

    def _write(self, sid: str, sock: zmq.Socket[bytes], kind: bytes, data: bytes) -> None:
        write(sock, kind + data, self.max_message_bytes, self.stats, self.system_id, sid)

    # -- receiving --------------------------------------------------------------------
    async def serve(self, deliver: Deliver, *, task_status: TaskStatus[None]) -> None:
        """Hand every valid envelope to ``deliver`` (called from a reader callback: it must
        not block; what it raises is logged) until cancelled or closed."""
        if self._closed:
            raise RuntimeError(f"transport of {self.system_id} is closed")
        if self._deliver is not None:
            raise RuntimeError(f"transport of {self.system_id} is already serving")
        loop = asyncio.get_running_loop()
        if self.curve is not None:
            self.curve.start(self._ctx, self._events.refusals.we_refused)
        try:
            loop.add_reader(self._fd, self._on_readable)
        except NotImplementedError:
            msg = "ZmqTransport needs an event loop with add_reader (on Windows: the selector loop)"
            raise RuntimeError(msg) from None
        self._loop = loop
        self._deliver = deliver
        self._stopped = loop.create_future()
        loop.add_reader(self._events.fd, self._on_events)
        # zmq's descriptors are edge-triggered: drain what arrived before we watched them.
        loop.call_soon(self._on_readable)
        loop.call_soon(self._on_events)
        for monitor in self._monitors.values():
            self._watch(monitor)
        folder = None if self.curve is None else self.curve.team.folder
        watch = None
        if folder is not None and self.trusted_poll_s > 0:
            every, seen = self.trusted_poll_s, self._first_listing
            poll = watch_trusted(self.system_id, folder, every, self._trust, seen)
            watch = asyncio.create_task(poll)
        task_status.started()
        try:
            await self._stopped
        finally:
            if watch is not None:
                watch.cancel()
                with contextlib.suppress(asyncio.CancelledError):
                    await watch
            self.close()
        self._raise_if_refused()

    def _on_readable(self) -> None:
        deliver = self._deliver
        if deliver is None:
            return
        secure = self.curve is not None
        recv, get, handle = self._recv, self._get, self._handle
        budget = _BATCH
        try:
            while budget > 0:
                try:
                    got = self._authenticated(*read_secure(recv)) if secure else read_plain(recv)
                except zmq.Again:  # a spurious wake-up: rare, so try first, ask never
                    return
                try:
                    junk = got is None or handle(got, deliver)
                except Exception as exc:  # a bug here must not stall the receiver
                    junk = True
                    self.stats.malformed += 1
                    self.stats.drop("receiver error")
                    log.error("transport.handle_failed", system=self.system_id, exc_info=exc)
                if self._deliver is None:  # closed by whoever we delivered to
                    return
                budget -= junk * _JUNK_COST + 1
                # Asking is cheaper than ending every drain with a zmq.Again raised.
                if not get(EVENTS) & POLLIN:  # type: ignore[operator]
                    return
        except zmq.ZMQError as exc:
            if not self._closed:
                log.error("transport.recv_failed", system=self.system_id, error=str(exc))
            return
        # Still more queued: the descriptor will not fire again for it, so come back.
        if self._loop is not None:
            self._loop.call_soon(self._on_readable)

    def _on_events(self) -> None:
        if not self._closed and self._events.drain(_BATCH) and self._loop is not None:
            self._loop.call_soon(self._on_events)

    def _authenticated(self, ident: bytes, part: zmq.Frame, extra: int) -> Received | None:
        member, problem = authenticated(ident, part)
        if problem:
            self._malformed(problem, member, "not the member ZAP admitted")
            return None
        if self._blocked(ident, member, part):
            return None
        return member, part.buffer, extra

    def _handle(self, got: Received, deliver: Deliver) -> int:
        """Take one message (see zmq_io); how much more of the batch than an ordinary one
        it costs: 1 (True) if it was junk, :data:`_HEAVY` if it was big."""
        ident, body, extra = got
        if extra:
            return self._malformed("frame count", ident, f"{extra + 2} frames")
        kind = body[0] if body else -1
        if kind == _MSG_BYTE:
            peer = self._known.get(ident)
            if peer is None:
                peer = self._recall(ident, body.obj)
            if peer is None:
                self.stats.unknown_peer += 1
                reject(self.stats, self.system_id, "unknown peer", ident, "no hello")
                return False
            screened = None
            if len(body) > _HEAVY_BYTES:  # before msgspec walks megabytes to the header's end
                screened = self._prescreen(peer, ident, body[1:])
                if screened:
                    return _HEAVY
            try:
                # A Frame's buffer is a memoryview already: sliced without a copy. The
                # message stays encoded until its sender, type and size have passed.
                kind, sender, recipient, raw, corr = self.codec.decode_header(body[1:])
            except CodecError as exc:
                return self._malformed("bad envelope", ident, str(exc)[:200])
            if sender.system != peer:
                return self._malformed("sender mismatch", ident, f"claims {sender.system[:64]!r}")
            to = recipient.system
            if to != self.system_id and to != BROADCAST:
                return self._malformed("wrong recipient", ident, f"for {to[:64]!r}")
            limited = peer in self._limited
            checks = screened is None and (limited or len(raw) > MAX_DEPTH)
            if checks and self._refused(peer, ident, kind, raw, limited):
                return _HEAVY if len(body) > _HEAVY_BYTES else True
            try:
                msg = self.codec.decode_body(raw)
            except CodecError as exc:
                return self._malformed("bad envelope", ident, str(exc)[:200])
            self.stats.received += 1
            if self._strangers.since:
                self._strangers.vouched(peer)
            if limited:
                self._observing(peer)
            try:
                deliver(Envelope(kind, sender, recipient, msg, corr))
            except Exception as exc:  # a bug above us must not stop the receive loop
                log.error(
                    "transport.deliver_failed", system=self.system_id, peer=peer, exc_info=exc
                )
            return screened is not None and _HEAVY
        return self._control(ident, kind, body)

    def _malformed(self, reason: str, ident: bytes, detail: str) -> bool:
        self.stats.malformed += 1
        reject(self.stats, self.system_id, reason, ident, detail)
        return True

    @property
    def closed(self) -> bool:
        return self._closed

    def close(self) -> None:
        """Close every socket, remove an ipc socket file, end :meth:`serve` (idempotent)."""
        if self._closed:
            return
        self._closed = True
        self._deliver = None
        for sid in list(self._dealers):
            self.remove_peer(sid)
        loop, self._loop = self._loop, None
        if loop is not None and not loop.is_closed():
            loop.remove_reader(self._fd)
            loop.remove_reader(self._events.fd)
        self._events.close()
        stopped, self._stopped = self._stopped, None
        if stopped is not None and not stopped.done():
            stopped.set_result(None)
        self._stop_rules()
        self._router.close(0)
        remove_ipc_file(self.bound_endpoint)
        if self.curve is not None:
            self.curve.stop()
        if self._own_ctx:
            self._ctx.term()
