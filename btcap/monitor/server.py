"""The monitor's web server (aiohttp): the page, ``/api/state`` and a WebSocket stream
(see :mod:`btcap.monitor.hub` for what it carries). Messages from a page are ignored,
except a replay's play/pause/seek: nothing on the page can change a robot.
"""

from __future__ import annotations

import asyncio
import contextlib
import socket
from collections.abc import Awaitable, Callable
from importlib.resources import files
from pathlib import Path
from typing import Any, Protocol
from urllib.parse import urlsplit

import msgspec
from aiohttp import WSMsgType, web

from btcap.monitor.hub import END, Hub
from btcap.monitor.net import LOCAL_NAMES, is_loopback
from btcap.transports.log import get_logger

__all__ = ["MonitorServer", "Source"]

log = get_logger(__name__)

STATIC = Path(str(files("btcap.monitor") / "static"))
#: Nothing is loaded from anywhere but this server.
CSP = "default-src 'self'; img-src 'self' data:; style-src 'self'; script-src 'self'"

#: How long a stopping server waits for the pages to be sent their last messages.
DRAIN_S = 2.0

_encode = msgspec.json.Encoder()
#: What a browser on this machine may call a loopback server.


class Source(Protocol):
    """What the server shows: a live monitor or a replay."""

    title: str

    def snapshot(self) -> dict[str, Any]: ...

    @property
    def hub(self) -> Hub: ...


class MonitorServer:
    """Serves one :class:`Source` on ``host:port`` (0: a free port) until stopped."""

    def __init__(self, source: Source, host: str, port: int, *, max_pages: int = 32) -> None:
        self.source = source
        self.host, self.port = host, port
        #: Open pages at most (each holds a queue and costs a snapshot to start): more are
        #: refused, so pages left open or opened in a loop cannot pile up.
        self.max_pages = max_pages
        source.hub.snapshot = source.snapshot
        self._runner: web.AppRunner | None = None
        self._sockets: set[web.WebSocketResponse] = set()
        self._pumps: set[asyncio.Task[None]] = set()

    @property
    def pages(self) -> int:
        """Pages connected now."""
        return len(self._sockets)

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}/"

    async def start(self) -> None:
        app = web.Application(middlewares=[self._guard, _headers])
        app.router.add_get("/", self._index)
        app.router.add_get("/api/state", self._state)
        app.router.add_get("/ws", self._ws)
        app.router.add_static("/static/", STATIC)
        family = socket.AF_INET6 if ":" in self.host else socket.AF_INET
        sock = socket.socket(family, socket.SOCK_STREAM)
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            sock.bind((self.host, self.port))
        except OSError as exc:
            sock.close()
            raise OSError(exc.errno, f"monitor: cannot listen on {self.host}:{self.port}: "
                                     f"{exc.strerror}") from None  # fmt: skip
        self.port = sock.getsockname()[1]
        self._runner = web.AppRunner(app, access_log=None)
        await self._runner.setup()
        await web.SockSite(self._runner, sock).start()
        log.info("monitor.serving", url=self.url)

    @web.middleware
    async def _guard(
        self, request: web.Request, handler: Callable[[web.Request], Awaitable[web.StreamResponse]]
    ) -> web.StreamResponse:
        """On loopback, only this machine's names for it (a web page elsewhere cannot
        reach it by DNS rebinding), and a WebSocket only from this page (browsers let
        any site open one)."""
        host = request.host
        if is_loopback(self.host) and host.rsplit(":", 1)[0] not in LOCAL_NAMES:
            raise web.HTTPForbidden(text=f"monitor: not served to host {host!r}")
        origin = request.headers.get("Origin")
        if origin is not None and urlsplit(origin).netloc != host:
            raise web.HTTPForbidden(text=f"monitor: not served to pages of {origin!r}")
        return await handler(request)

    async def stop(self) -> None:
        """Send each page what is queued for it (how the run ended: the page keeps the
        final picture), waiting at most :data:`DRAIN_S`, then close every page."""
        self.source.hub.close()
        if self._pumps:
            await asyncio.wait(self._pumps, timeout=DRAIN_S)
        for ws in list(self._sockets):
            await ws.close()
        if self._runner is not None:
            await self._runner.cleanup()
            self._runner = None

    async def _index(self, _request: web.Request) -> web.StreamResponse:
        return web.FileResponse(STATIC / "index.html")

    async def _state(self, _request: web.Request) -> web.Response:
        return web.Response(body=_encode.encode(self.source.snapshot()),
                            content_type="application/json")  # fmt: skip

    async def _ws(self, request: web.Request) -> web.WebSocketResponse:
        if len(self._sockets) >= self.max_pages:
            raise web.HTTPServiceUnavailable(
                text=f"monitor: {self.max_pages} pages are open already; close one"
            )
        ws = web.WebSocketResponse(heartbeat=20.0)
        await ws.prepare(request)
        hub = self.source.hub
        q = hub.join()
        self._sockets.add(ws)
        sender = asyncio.get_running_loop().create_task(_pump(q, ws), name="monitor client")
        self._pumps.add(sender)
        try:
            async for msg in ws:
                control = getattr(self.source, "control", None)
                if msg.type == WSMsgType.TEXT and control is not None:
                    with contextlib.suppress(ValueError, TypeError, KeyError):
                        control(msgspec.json.decode(msg.data))
        finally:
            hub.leave(q)
            self._sockets.discard(ws)
            self._pumps.discard(sender)
            sender.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await sender
        return ws


async def _pump(q: asyncio.Queue[bytes], ws: web.WebSocketResponse) -> None:
    with contextlib.suppress(ConnectionError, RuntimeError):
        while (msg := await q.get()) != END:
            await ws.send_str(msg.decode())
        await ws.close()


@web.middleware
async def _headers(
    request: web.Request, handler: Callable[[web.Request], Awaitable[web.StreamResponse]]
) -> web.StreamResponse:
    response = await handler(request)
    response.headers["Content-Security-Policy"] = CSP
    response.headers["X-Content-Type-Options"] = "nosniff"
    response.headers["Cache-Control"] = "no-store"
    return response
