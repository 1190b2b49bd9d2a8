"""ZeroMQ transport: one ROUTER bound per system, one DEALER per peer.

Frames on the wire are ``[kind, payload]`` from a DEALER whose routing id is the sending
system's id, so the receiving ROUTER sees ``[system_id, kind, payload]``:

- ``kind == b"M"``: ``payload`` is a codec-encoded :class:`~transports.codec.Envelope`;
- ``kind == b"H"``: ``payload`` is the sender's endpoint (UTF-8): a hello that lets a
  system that joins later be answered without anyone configuring it.

Anything else, a frame from a peer that never said hello, or an envelope whose sender
does not match the routing id is dropped, logged and counted; the receiver goes on.
"""

from __future__ import annotations

import structlog
import zmq
import zmq.asyncio
from anyio.abc import TaskStatus

from transports.base import BROADCAST, Deliver, Transport, TransportStats
from transports.codec import Codec, CodecError, Envelope
from transports.message import MessageRegistry

__all__ = ["ZmqTransport"]

log = structlog.get_logger("transports")

_MSG = b"M"
_HELLO = b"H"
_SEND_HWM = 10_000


class ZmqTransport(Transport):
    """Reach peers over ``inproc://``, ``ipc://`` or ``tcp://``.

    ``bind`` may use port ``*`` (``tcp://127.0.0.1:*``); :attr:`endpoint` then tells the
    port chosen. ``peers`` maps system ids to endpoints; more can be added at run time,
    and with ``accept_hello`` (default) any system that says hello becomes a peer.
    """

    def __init__(
        self,
        system_id: str,
        bind: str,
        registry: MessageRegistry,
        *,
        peers: dict[str, str] | None = None,
        accept_hello: bool = True,
        context: zmq.asyncio.Context | None = None,
    ) -> None:
        if not system_id or system_id == BROADCAST or "/" in system_id:
            raise ValueError(f"system id {system_id!r}: expected a non-empty id without '/'")
        self.system_id = system_id
        self.stats = TransportStats()
        self.codec = Codec(registry)
        self.accept_hello = accept_hello
        self._id = system_id.encode()
        self._ctx = context or zmq.asyncio.Context.instance()
        # Sends are non-blocking C calls, so a plain socket on the same context is cheaper
        # than an asyncio one; only the receiving side needs the event loop.
        self._sync_ctx = zmq.Context.shadow(self._ctx.underlying)
        self._router = self._ctx.socket(zmq.ROUTER)
        self._router.setsockopt(zmq.LINGER, 0)
        self._router.setsockopt(zmq.RCVHWM, 0)
        try:
            self._router.bind(bind)
        except zmq.ZMQError as exc:
            self._router.close(0)
            raise ValueError(f"cannot bind {bind!r}: {exc}") from None
        self.endpoint: str = self._router.getsockopt(zmq.LAST_ENDPOINT).decode()
        self._dealers: dict[str, zmq.Socket[bytes]] = {}
        self._endpoints: dict[str, str] = {}
        self._closed = False
        for sid, ep in (peers or {}).items():
            self.add_peer(sid, ep)

    # -- peers ------------------------------------------------------------------------
    def add_peer(self, system_id: str, endpoint: str) -> None:
        """Connect to a peer (idempotent; a new endpoint replaces the old connection)."""
        if system_id == self.system_id:
            return
        if self._endpoints.get(system_id) == endpoint:
            return
        self.remove_peer(system_id)
        sock: zmq.Socket[bytes] = self._sync_ctx.socket(zmq.DEALER)
        sock.setsockopt(zmq.LINGER, 0)
        sock.setsockopt(zmq.ROUTING_ID, self._id)
        sock.setsockopt(zmq.SNDHWM, _SEND_HWM)
        sock.setsockopt(zmq.IMMEDIATE, 0)
        try:
            sock.connect(endpoint)
        except zmq.ZMQError as exc:
            sock.close(0)
            raise ValueError(f"peer {system_id}: cannot connect to {endpoint!r}: {exc}") from None
        self._dealers[system_id] = sock
        self._endpoints[system_id] = endpoint
        self._write(system_id, sock, _HELLO, self.endpoint.encode())

    def remove_peer(self, system_id: str) -> None:
        sock = self._dealers.pop(system_id, None)
        self._endpoints.pop(system_id, None)
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
        sock = self._dealers.get(target)
        if sock is None:
            self.stats.undeliverable += 1
            self.stats.drop(f"no peer {target}")
            return
        self._write(target, sock, _MSG, data)

    def _write(self, sid: str, sock: zmq.Socket[bytes], kind: bytes, data: bytes) -> None:
        try:
            sock.send_multipart((kind, data), flags=zmq.NOBLOCK, copy=len(data) < 65536)
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
        router = self._router
        # The asyncio socket waits; a plain shadow of it drains without a trip to the loop.
        drain: zmq.Socket[bytes] = zmq.Socket.shadow(router.underlying)
        task_status.started()
        try:
            while True:
                frames = await router.recv_multipart(copy=True)
                self._handle(frames, deliver)
                # Drain whatever else is already queued without another trip to the loop.
                while True:
                    try:
                        frames = drain.recv_multipart(flags=zmq.NOBLOCK, copy=True)
                    except zmq.Again:
                        break
                    self._handle(frames, deliver)
        finally:
            self.close()

    def _handle(self, frames: list[bytes], deliver: Deliver) -> None:
        if len(frames) != 3:
            self._reject("frame count", frames[0] if frames else b"?", f"{len(frames)} frames")
            return
        ident, kind, payload = frames
        try:
            peer = ident.decode()
        except UnicodeDecodeError:
            self._reject("bad routing id", ident, "not UTF-8")
            return
        if kind == _HELLO:
            self._hello(peer, payload)
            return
        if kind != _MSG:
            self._reject("unknown frame kind", ident, repr(kind[:8]))
            return
        if peer not in self._dealers:
            self.stats.unknown_peer += 1
            self._reject("unknown peer", ident, "no hello")
            return
        try:
            env = self.codec.decode(payload)
        except CodecError as exc:
            self.stats.malformed += 1
            self._reject("malformed", ident, str(exc)[:200])
            return
        if env.sender.system != peer:
            self._reject("sender mismatch", ident, f"claims {env.sender.system!r}")
            return
        self.stats.received += 1
        try:
            deliver(env)
        except Exception as exc:  # a bug above us must not stop the receive loop
            log.error("transport.deliver_failed", system=self.system_id, peer=peer, exc_info=exc)

    def _hello(self, peer: str, payload: bytes) -> None:
        try:
            endpoint = payload.decode()
        except UnicodeDecodeError:
            self._reject("bad hello", peer.encode(), "endpoint not UTF-8")
            return
        if not endpoint.startswith(("tcp://", "ipc://", "inproc://")) or peer in ("", BROADCAST):
            self._reject("bad hello", peer.encode(), f"endpoint {endpoint[:80]!r}")
            return
        if peer in self._dealers or not self.accept_hello:
            if peer not in self._dealers:
                self.stats.unknown_peer += 1
                self._reject("unknown peer", peer.encode(), "hello refused")
            return
        self.add_peer(peer, endpoint)

    def _reject(self, reason: str, ident: bytes, detail: str) -> None:
        self.stats.drop(reason)
        log.warning(
            "transport.dropped",
            system=self.system_id,
            peer=ident[:64].decode(errors="replace"),
            reason=reason,
            detail=detail,
        )

    def close(self) -> None:
        """Close every socket (the shared context stays up for other users)."""
        if self._closed:
            return
        self._closed = True
        for sid in list(self._dealers):
            self.remove_peer(sid)
        self._router.close(0)
