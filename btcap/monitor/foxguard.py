"""The door of the live Foxglove server: the monitor page's rules for who may connect.

The Foxglove SDK's server answers any WebSocket, whatever its ``Host`` and ``Origin``,
and its API has no setting for them; browsers let any web site open a WebSocket to
``ws://127.0.0.1:PORT``. So the SDK's server listens on a loopback port of its own, and
:class:`FoxgloveGuard` listens where ``--foxglove`` says, reads each connection's HTTP
request head and hands the connection on to the SDK byte for byte only if:

- bound to loopback, its ``Host`` is one of this machine's names (DNS rebinding);
- it has no ``Origin`` (a program, a script), or one of this machine (a page served
  here), or Foxglove's web app (:data:`VIEWER_ORIGINS`), or one that is not a web site's
  (``http``/``https``): a desktop app's page (Foxglove's and Lichtblick's are Electron
  apps; Chromium says ``null`` for a ``file:`` page, an app's own scheme otherwise).

Anything else is answered ``403 Forbidden`` and closed. What it cannot stop: Chromium
says ``null`` for a sandboxed frame of any site too, the very header a desktop app's
``file:`` page sends (nothing else in the request differs), so a site that opens the
WebSocket from such a frame is served; refusing ``null`` would refuse the desktop apps.

The guard runs an event loop on a thread of its own, so the run's loop is not held; a
client that reads slowly holds only its own relay (each side waits for the other to take
what it has), and the SDK's queue for it drops the oldest messages as before. At most
:data:`PENDING_MAX` connections wait to send their request head (for at most
:data:`HEAD_S` each), the oldest making room: clients that connect and say nothing cannot
hold the run's descriptors (it shares them with its ZeroMQ sockets).
"""

from __future__ import annotations

import asyncio
import contextlib
import secrets
import socket
import threading
from collections import OrderedDict
from urllib.parse import urlsplit

from btcap.monitor.net import LOCAL_NAMES, is_loopback

__all__ = [
    "HEAD_MAX",
    "HEAD_S",
    "PENDING_MAX",
    "VIEWER_ORIGINS",
    "FoxgloveGuard",
    "hidden_loopback",
    "refusal",
]

#: Web apps that may open the live view from a browser (Foxglove's).
VIEWER_ORIGINS = frozenset({"https://app.foxglove.dev", "https://studio.foxglove.dev"})
#: Bytes of a request head at most, and seconds to send it in.
HEAD_MAX = 16 * 1024
HEAD_S = 10.0
#: Connections waiting for their request head at most (a viewer sends it at once).
PENDING_MAX = 64
_CHUNK = 64 * 1024
_FORBIDDEN = b"HTTP/1.1 403 Forbidden\r\nContent-Length: 0\r\nConnection: close\r\n\r\n"


def refusal(head: bytes, loopback: bool) -> str | None:
    """Why a request head is refused, or None to serve it (see the module's rules)."""
    headers: dict[str, str] = {}
    for line in head.decode("latin-1").split("\r\n")[1:]:
        name, sep, value = line.partition(":")
        if sep:
            headers[name.strip().lower()] = value.strip()
    host = headers.get("host", "")
    if loopback and _hostname(host) not in LOCAL_NAMES:
        return f"Host {host!r} is not this machine"
    origin = headers.get("origin")
    if origin is None or origin in VIEWER_ORIGINS:
        return None
    parts = urlsplit(origin)
    if parts.scheme not in ("http", "https"):
        return None  # a desktop app's page (file: is "null", app:): see the module's doc
    if parts.hostname is not None and is_loopback(parts.hostname):
        return None
    return f"Origin {origin!r} is another site"


def hidden_loopback() -> str:
    """A random address of 127.0.0.0/8 for the SDK's own server: a page that may reach
    any loopback port cannot guess it (nor the port), so it cannot pass the guard by."""
    return "127." + ".".join(str(1 + secrets.randbelow(254)) for _ in range(3))


def _hostname(host: str) -> str:
    """A ``Host`` header without its port (``[::1]:8765`` -> ``[::1]``), lower case."""
    if host.startswith("["):
        return host[: host.find("]") + 1].lower()
    return host.rsplit(":", 1)[0].lower()


class FoxgloveGuard:
    """Listens on ``host``:``port`` (0: a free port) and relays the connections it lets in
    to the SDK's server on ``inner_host``:``inner``; :meth:`close` stops it and its thread."""

    def __init__(self, host: str, port: int, inner: int, inner_host: str = "127.0.0.1") -> None:
        self.refused = 0  #: connections answered 403 (for tests)
        self._inner = inner
        self._inner_host = inner_host
        self._loopback = is_loopback(host)
        self._tasks: set[asyncio.Task[None]] = set()
        self._closing = False
        #: The connections whose head is awaited, oldest first.
        self._pending: OrderedDict[asyncio.Task[None], None] = OrderedDict()
        # one socket, as the monitor page binds (``localhost`` is 127.0.0.1: one port)
        sock = socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET)
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            sock.bind((host, port))
        except BaseException:
            sock.close()
            raise
        self.port: int = sock.getsockname()[1]
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._loop.run_forever, name="foxglove-guard")
        self._thread.daemon = True
        self._thread.start()
        # served by the guard's loop (the caller's may be running)
        start = asyncio.start_server(self._serve, sock=sock, limit=HEAD_MAX)
        try:
            self._server = asyncio.run_coroutine_threadsafe(start, self._loop).result()
        except BaseException:
            sock.close()
            self._end()
            raise

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        if self._closing:  # accepted as the guard closed: its task starts only now
            writer.close()
            return
        task = asyncio.current_task()
        assert task is not None
        self._tasks.add(task)
        self._pending[task] = None
        while len(self._pending) > PENDING_MAX:  # the oldest silent one makes room
            self._pending.popitem(last=False)[0].cancel()
        try:
            try:
                head = await asyncio.wait_for(reader.readuntil(b"\r\n\r\n"), HEAD_S)
            except (asyncio.IncompleteReadError, asyncio.LimitOverrunError, TimeoutError):
                return  # not a request: closed below
            finally:
                self._pending.pop(task, None)
            if refusal(head, self._loopback) is not None:
                self.refused += 1
                writer.write(_FORBIDDEN)
                await writer.drain()
                return
            inner_r, inner_w = await asyncio.open_connection(self._inner_host, self._inner)
            try:
                inner_w.write(head)
                await asyncio.gather(_pipe(reader, inner_w), _pipe(inner_r, writer))
            finally:
                inner_w.close()
        except (ConnectionError, OSError):
            pass  # either side went away
        except asyncio.CancelledError:
            pass  # the guard closes (:meth:`close`): the task ends here, said to nobody
        finally:
            writer.close()
            self._tasks.discard(task)

    def close(self) -> None:
        """Stop listening, end every relay and the thread (waits for them)."""
        if self._thread.is_alive():
            asyncio.run_coroutine_threadsafe(self._shutdown(), self._loop).result()
            self._end()

    async def _shutdown(self) -> None:
        """End every task of the guard's loop: the relays, and those of connections
        accepted just before (a task not started yet would never close its socket)."""
        self._closing = True
        for sock in self._server.sockets:  # no more accepts; those under way end first
            self._loop.remove_reader(sock.fileno())  # (3.11 leaks one that ends after close)
        me = asyncio.current_task()
        while tasks := asyncio.all_tasks() - {me}:
            for task in tasks & self._tasks:
                task.cancel()
            await asyncio.wait(tasks)
        self._server.close()
        await self._server.wait_closed()

    def _end(self) -> None:
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join()
        self._loop.close()


async def _pipe(src: asyncio.StreamReader, dst: asyncio.StreamWriter) -> None:
    """Copy until ``src`` ends, waiting for ``dst`` to take each chunk; then end ``dst``."""
    try:
        while data := await src.read(_CHUNK):
            dst.write(data)
            await dst.drain()
    finally:
        with contextlib.suppress(OSError, RuntimeError):
            if dst.can_write_eof():
                dst.write_eof()
