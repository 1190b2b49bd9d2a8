"""ZeroMQ transport: one ROUTER bound per system, one DEALER per peer.

A DEALER whose routing id is the sending system's id sends one frame per message: a kind
byte followed by the payload, so the receiving ROUTER sees ``[system_id, kind+payload]``:

- kind ``M``: the payload is a codec-encoded :class:`~transports.codec.Envelope`;
- kind ``H``: the payload is the sender's endpoint (UTF-8): a hello that lets a system
  that joins later be answered without anyone configuring it.

Anything else, a message from a peer that never said hello, or an envelope whose sender
does not match the routing id is dropped, logged and counted; the receiver goes on.

All sockets are plain (non-asyncio) pyzmq sockets. Sends never block (``NOBLOCK``), and
receiving is a reader callback on the ROUTER's file descriptor that drains the socket and
hands envelopes straight to the actor system: no futures and no task switch per message.
One frame instead of two saves a ``recv``/``send`` and a ``RCVMORE`` query per message,
which is most of what a round trip costs in Python.
"""

from __future__ import annotations

import asyncio
from typing import Any

import zmq
import zmq.asyncio
from anyio.abc import TaskStatus

from btcap.transports.base import BROADCAST, Deliver, Transport, TransportStats
from btcap.transports.codec import Codec, CodecError, Envelope
from btcap.transports.log import get_logger, worth_logging
from btcap.transports.message import MessageRegistry
from btcap.transports.zmq_sockets import EVENTS, NOBLOCK, POLLIN, Monitor, check_id, open_dealer

__all__ = ["ZmqTransport"]

log = get_logger("btcap.transports")

_MSG = b"M"
_HELLO = b"H"
_MSG_BYTE = _MSG[0]
_HELLO_BYTE = _HELLO[0]
_SCHEMES = ("tcp://", "ipc://", "inproc://")
_RECV_HWM = 10_000
_BATCH = 256
"""Messages handled per reader callback before other callbacks get a turn."""
_COPY_THRESHOLD = 65_536
"""Smaller payloads are copied into the frame (cheaper than tracking a zero-copy buffer)."""


class ZmqTransport(Transport):
    """Reach peers over ``inproc://``, ``ipc://`` or ``tcp://``.

    ``bind`` may use port ``*`` (``tcp://127.0.0.1:*``); :attr:`endpoint` then tells the
    port chosen. Bound to a wildcard address (``tcp://0.0.0.0:7000``), pass ``advertise``:
    the endpoint other hosts should connect to, sent in hellos. ``peers`` maps system ids
    to endpoints; more can be added at run time, and with ``accept_hello`` (default) any
    system that says hello becomes a peer, up to ``max_peers``. A peer learnt from a
    hello that says hello again from a new endpoint (it restarted elsewhere) is
    reconnected there; endpoints given in ``peers`` or :meth:`add_peer` stay as given.

    ``inproc://`` endpoints only reach transports on the same zmq context (by default the
    process-wide ``zmq.asyncio.Context.instance()``). Use a transport from one thread,
    the one running its event loop.
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
    ) -> None:
        if (why := check_id(system_id)) is not None:
            raise ValueError(f"system id {system_id!r}: {why}")
        if not bind.startswith(_SCHEMES):
            raise ValueError(f"cannot bind {bind!r}: expected tcp://, ipc:// or inproc://")
        if advertise is not None and not advertise.startswith(_SCHEMES):
            raise ValueError(f"advertise {advertise!r}: expected tcp://, ipc:// or inproc://")
        self.system_id = system_id
        self.stats = TransportStats()
        self.codec = Codec(registry)
        self.accept_hello = accept_hello
        self.max_peers = max_peers
        self._id = system_id.encode()
        base = context if context is not None else zmq.asyncio.Context.instance()
        # Plain sockets on the same underlying context (so inproc:// still connects):
        # sends are non-blocking C calls and receiving is our own reader callback.
        self._ctx: zmq.Context[zmq.Socket[bytes]] = zmq.Context.shadow(base.underlying)
        self._router: zmq.Socket[bytes] = self._ctx.socket(zmq.ROUTER)
        self._router.setsockopt(zmq.LINGER, 0)
        self._router.setsockopt(zmq.RCVHWM, _RECV_HWM)
        # A peer that reconnects with the same id (after a network blip or a restart)
        # takes over its old connection instead of being silently ignored.
        self._router.setsockopt(zmq.ROUTER_HANDOVER, 1)
        try:
            self._router.bind(bind)
        except zmq.ZMQError as exc:
            self._router.close(0)
            raise ValueError(f"cannot bind {bind!r}: {exc}") from None
        bound = self._router.getsockopt_string(zmq.LAST_ENDPOINT)
        fd = self._router.getsockopt(zmq.FD)
        assert isinstance(fd, int)
        self._fd = fd
        self.endpoint: str = advertise or bound
        """Where peers reach this system: ``advertise`` if given, else what was bound."""
        self.bound_endpoint: str = bound
        self._dealers: dict[str, zmq.Socket[bytes]] = {}
        self._endpoints: dict[str, str] = {}
        self._configured: set[str] = set()
        self._known: dict[bytes, str] = {}
        self._monitors: dict[str, Monitor] = {}
        self.hellos = 0
        """Hellos taken (new, moved or known peers): with ``stats.received``,
        ``stats.malformed`` and ``stats.unknown_peer`` every inbound frame is counted once."""
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

    def __repr__(self) -> str:
        return f"ZmqTransport({self.system_id!r}, {self.endpoint!r}, peers={len(self._dealers)})"

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
        if not endpoint.startswith(_SCHEMES):
            raise ValueError(f"peer {system_id}: endpoint {endpoint!r} is not tcp/ipc/inproc")
        sock, monitor = open_dealer(self._ctx, self._id, system_id, endpoint)
        self.remove_peer(system_id)
        self._dealers[system_id] = sock
        self._endpoints[system_id] = endpoint
        self._known[system_id.encode()] = system_id
        # The first hello waits in the DEALER's queue until the connection is up.
        self._write(system_id, sock, _HELLO, self.endpoint.encode())
        if monitor is not None:
            self._monitors[system_id] = monitor
            if self._loop is not None:
                self._watch(monitor)

    def _watch(self, monitor: Monitor) -> None:
        assert self._loop is not None
        self._loop.add_reader(monitor.fd, self._on_monitor, monitor)
        # Events that came before we watched have already reset the descriptor.
        self._loop.call_soon(self._on_monitor, monitor)

    def remove_peer(self, system_id: str) -> None:
        """Forget a peer: messages to it become undeliverable, messages from it dropped."""
        sock = self._dealers.pop(system_id, None)
        self._endpoints.pop(system_id, None)
        self._configured.discard(system_id)
        self._known.pop(system_id.encode(), None)
        monitor = self._monitors.pop(system_id, None)
        if monitor is not None:
            if self._loop is not None and not self._loop.is_closed():
                self._loop.remove_reader(monitor.fd)
            monitor.close()
        if sock is not None:
            sock.close(0)

    def peers(self) -> frozenset[str]:
        return frozenset(self._dealers)

    def peer_endpoints(self) -> dict[str, str]:
        return dict(self._endpoints)

    # -- sending ----------------------------------------------------------------------
    def send(self, env: Envelope) -> None:
        data = self.codec.encode(env)
        target = env.recipient.system
        if target == BROADCAST:
            for sid, sock in list(self._dealers.items()):
                self._write(sid, sock, _MSG, data)
            return
        dealer = self._dealers.get(target)
        if dealer is None:
            self.stats.undeliverable += 1
            self.stats.drop(f"no peer {target}")
            return
        self._write(target, dealer, _MSG, data)

    def _write(self, sid: str, sock: zmq.Socket[bytes], kind: bytes, data: bytes) -> None:
        frame = kind + data
        try:
            sock.send(frame, NOBLOCK, copy=len(frame) < _COPY_THRESHOLD)
        except zmq.Again:
            self.stats.undeliverable += 1
            self.stats.drop(f"peer {sid} backed up")
        except zmq.ZMQError as exc:
            self.stats.undeliverable += 1
            self.stats.drop(f"peer {sid}: {exc.strerror}")
        else:
            self.stats.sent += 1

    # -- receiving --------------------------------------------------------------------
    async def serve(self, deliver: Deliver, *, task_status: TaskStatus[None]) -> None:
        """Hand every valid envelope to ``deliver`` until cancelled or closed.

        ``deliver`` is called from a reader callback of the running asyncio loop, so it
        must not block; exceptions it raises are logged and the receiver goes on.
        """
        if self._closed:
            raise RuntimeError(f"transport of {self.system_id} is closed")
        if self._deliver is not None:
            raise RuntimeError(f"transport of {self.system_id} is already serving")
        loop = asyncio.get_running_loop()
        try:
            loop.add_reader(self._fd, self._on_readable)
        except NotImplementedError:
            raise RuntimeError(
                "ZmqTransport needs an event loop with add_reader (on Windows, the "
                "selector event loop)"
            ) from None
        self._loop = loop
        self._deliver = deliver
        self._stopped = loop.create_future()
        # zmq's descriptors are edge-triggered: drain what arrived before we watched them.
        loop.call_soon(self._on_readable)
        for monitor in self._monitors.values():
            self._watch(monitor)
        task_status.started()
        try:
            await self._stopped
        finally:
            self.close()

    def _on_readable(self) -> None:
        deliver = self._deliver
        if deliver is None:
            return
        router = self._router
        try:
            for _ in range(_BATCH):
                try:
                    frames = router.recv_multipart(NOBLOCK)
                except zmq.Again:  # a spurious wake-up: rare, so try first, ask never
                    return
                try:
                    self._handle(frames, deliver)
                except Exception as exc:  # a bug here must not stall the receiver
                    self.stats.malformed += 1
                    self.stats.drop("receiver error")
                    log.error("transport.handle_failed", system=self.system_id, exc_info=exc)
                if self._deliver is None:  # closed by whoever we delivered to
                    return
                # Asking is cheaper than ending every drain with a zmq.Again raised.
                if not router.getsockopt(EVENTS) & POLLIN:  # type: ignore[operator]
                    return
        except zmq.ZMQError as exc:
            if not self._closed:
                log.error("transport.recv_failed", system=self.system_id, error=str(exc))
            return
        # Still more queued: the descriptor will not fire again for it, so come back.
        if self._loop is not None:
            self._loop.call_soon(self._on_readable)

    def _on_monitor(self, monitor: Monitor) -> None:
        try:
            for _ in range(_BATCH):
                if monitor.closed or not monitor.pending():
                    return
                if monitor.connected() and monitor.connects > 1:
                    log.info("transport.peer_reconnected", system=self.system_id, peer=monitor.peer)
                    self._write(monitor.peer, monitor.dealer, _HELLO, self.endpoint.encode())
        except zmq.ZMQError as exc:
            log.warning("transport.monitor_failed", peer=monitor.peer, error=str(exc))
            return
        if self._loop is not None:
            self._loop.call_soon(self._on_monitor, monitor)

    def _handle(self, frames: list[bytes], deliver: Deliver) -> None:
        if len(frames) != 2:
            self._malformed("frame count", frames[0], f"{len(frames)} frames")
            return
        ident, body = frames
        kind = body[0] if body else -1
        if kind == _MSG_BYTE:
            peer = self._known.get(ident)
            if peer is None:
                self.stats.unknown_peer += 1
                self._reject("unknown peer", ident, "no hello")
                return
            try:
                env = self.codec.decode(memoryview(body)[1:])
            except CodecError as exc:
                self._malformed("bad envelope", ident, str(exc)[:200])
                return
            if env.sender.system != peer:
                self._malformed("sender mismatch", ident, f"claims {env.sender.system[:64]!r}")
                return
            to = env.recipient.system
            if to != self.system_id and to != BROADCAST:
                self._malformed("wrong recipient", ident, f"for {to[:64]!r}")
                return
            self.stats.received += 1
            try:
                deliver(env)
            except Exception as exc:  # a bug above us must not stop the receive loop
                log.error(
                    "transport.deliver_failed", system=self.system_id, peer=peer, exc_info=exc
                )
        elif kind == _HELLO_BYTE:
            self._hello(ident, body[1:])
        else:
            self._malformed("unknown frame kind", ident, repr(body[:8]))

    def _hello(self, ident: bytes, payload: bytes) -> None:
        try:
            peer = ident.decode()
            endpoint = payload.decode()
        except UnicodeDecodeError:
            self._malformed("bad hello", ident, "id or endpoint not UTF-8")
            return
        if (why := check_id(peer)) is not None:
            self._malformed("bad hello", ident, why)
            return
        if not endpoint.startswith(_SCHEMES) or len(endpoint) > 1024:
            self._malformed("bad hello", ident, f"endpoint {endpoint[:80]!r}")
            return
        if peer == self.system_id:
            self._malformed("bad hello", ident, "another system uses our id")
            return
        known = self._endpoints.get(peer)
        if known != endpoint and peer not in self._configured:
            if known is None and not self.accept_hello:
                self.stats.unknown_peer += 1
                self._reject("unknown peer", ident, "hello refused")
                return
            if known is None and len(self._dealers) >= self.max_peers:
                # Every peer costs sockets: a flood of made-up ids must not exhaust them.
                self.stats.unknown_peer += 1
                self._reject("too many peers", ident, f"already {len(self._dealers)}")
                return
            try:
                self._connect(peer, endpoint)
            except (ValueError, RuntimeError) as exc:
                self._malformed("bad hello", ident, str(exc)[:200])
                return
            event = "transport.peer_joined" if known is None else "transport.peer_moved"
            log.info(event, system=self.system_id, peer=peer, endpoint=endpoint)
        self.hellos += 1

    def _malformed(self, reason: str, ident: bytes, detail: str) -> None:
        self.stats.malformed += 1
        self._reject(reason, ident, detail)

    def _reject(self, reason: str, ident: bytes, detail: str) -> None:
        stats = self.stats
        stats.drop(reason)
        n = stats.by_reason[reason]
        # A flood of junk must not become a flood of log lines: log the first few of
        # each reason, then every power of two.
        if worth_logging(n):
            log.warning(
                "transport.dropped",
                system=self.system_id,
                peer=ident[:64].decode(errors="replace"),
                reason=reason,
                detail=detail,
                count=n,
            )

    # -- shutting down ----------------------------------------------------------------
    @property
    def closed(self) -> bool:
        return self._closed

    def close(self) -> None:
        """Close every socket and end :meth:`serve` (idempotent; the context stays up)."""
        if self._closed:
            return
        self._closed = True
        self._deliver = None
        for sid in list(self._dealers):
            self.remove_peer(sid)
        loop, self._loop = self._loop, None
        if loop is not None and not loop.is_closed():
            loop.remove_reader(self._fd)
        stopped, self._stopped = self._stopped, None
        if stopped is not None and not stopped.done():
            stopped.set_result(None)
        self._router.close(0)
