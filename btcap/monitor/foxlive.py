"""The monitor's channels live over the Foxglove WebSocket protocol (``--foxglove``).

The Foxglove SDK (package ``foxglove-sdk``, a dependency of btcap) serves
them: its server runs on a thread of its own (Rust), and a message handed to it is queued
there, so the event loop only encodes each batch's messages once, as the MCAP recorder
does (:class:`btcap.monitor.channels.Channels`: the same topics, schemas and bytes, the
clock time as log time). Foxglove or Lichtblick connect to ``ws://HOST:PORT``.

Every channel btcap knows is advertised at the start, so a client can subscribe before
the run sends anything. A client that subscribes later is sent, on subscribing, the last
message of each channel that is a picture rather than news (the map, the scene, the
trees; ``/tf`` and ``/btcap/world``, which hold what changed, as the whole picture so
far): Foxglove's 3D panel shows the world at once, not from the next change.

The SDK's server checks neither ``Host`` nor ``Origin``; it listens on a loopback port of
its own, behind :class:`~btcap.monitor.foxguard.FoxgloveGuard`, which keeps the monitor
page's rules (no DNS rebinding, no other web site's page). A page can reach any loopback
port, and scanning 127.0.0.1's ports takes a script minutes: so the SDK's port is on a
random address of 127.0.0.0/8 (Linux answers on all of it), about 2^38 places to look,
and on 127.0.0.1 only where no other can be bound.
"""

from __future__ import annotations

import asyncio
import threading
from collections.abc import Iterable
from typing import Any

import foxglove
import msgspec
from foxglove.websocket import ChannelView, Client, ServerListener

from btcap.monitor.channels import EVENT_TOPICS, LOG_SCHEMA, LOG_TOPIC, Channels
from btcap.monitor.foxguard import FoxgloveGuard, hidden_loopback
from btcap.monitor.scene import SCENE_TOPICS
from btcap.monitor.view import Event

__all__ = ["BACKLOG", "LATCHED", "FoxgloveLive"]

#: Messages the SDK queues per client before it drops the oldest (a slow client).
BACKLOG = 4096
#: Topics whose last message a client is sent when it subscribes.
LATCHED = frozenset({*SCENE_TOPICS, "/btcap/map", "/btcap/world", "/btcap/robots"})

_encode = msgspec.json.Encoder()
WORLD_TOPIC = EVENT_TOPICS["world"][0]


class _Listener(ServerListener):
    """The SDK's callbacks (on its thread): subscriptions are counted and handed to the
    event loop, which sends the latched message."""

    def __init__(self, live: FoxgloveLive, loop: asyncio.AbstractEventLoop) -> None:
        self._live, self._loop = live, loop

    def on_subscribe(self, client: Client, channel: ChannelView) -> None:
        with self._live.lock:
            self._live.subscriptions += 1
        self._loop.call_soon_threadsafe(self._live.resend, channel.topic)

    def on_unsubscribe(self, client: Client, channel: ChannelView) -> None:
        with self._live.lock:
            self._live.subscriptions -= 1


class FoxgloveLive:
    """A Foxglove WebSocket server on ``host``:``port`` (0: a free one) sending every
    batch of monitor events as :class:`~btcap.monitor.channels.Channels` does; call in
    the event loop."""

    def __init__(self, host: str, port: int) -> None:
        self._context = foxglove.Context()
        self._channels: dict[str, foxglove.Channel] = {}
        self._last: dict[str, tuple[bytes, int]] = {}
        self._encoder = Channels()
        self.lock = threading.Lock()
        self.subscriptions = 0  #: channels subscribed, over all clients (for tests)
        self.sent = 0  #: messages handed to the SDK
        for topic, schema in [
            *EVENT_TOPICS.values(),
            (LOG_TOPIC, LOG_SCHEMA),
            *SCENE_TOPICS.items(),
        ]:
            self._channel(topic, schema)
        listener = _Listener(self, asyncio.get_running_loop())
        where = f"[{host}]:{port}" if ":" in host else f"{host}:{port}"
        # The SDK's server on a loopback port of its own, behind the guard (the monitor
        # page's rules for Host and Origin, which the SDK does not check).
        for inner in (hidden_loopback(), "127.0.0.1"):  # the latter: 127.0.0.1 alone (macOS)
            try:
                self._server = foxglove.start_server(
                    name="btcap",
                    host=inner,
                    port=0,
                    context=self._context,
                    server_listener=listener,
                    message_backlog_size=BACKLOG,
                )
                break
            except RuntimeError as exc:  # the SDK's FoxgloveError
                why = str(exc).removeprefix("FoxgloveError: ")
        else:
            raise OSError(f"the Foxglove server cannot listen on {where}: {why}") from None
        try:
            self._guard = FoxgloveGuard(host, port, self._server.port, inner)
        except OSError as exc:  # a port in use, a host unknown
            self._server.stop()
            why = exc.strerror or str(exc)
            raise OSError(f"the Foxglove server cannot listen on {where}: {why}") from None
        self.port: int = self._guard.port
        self._closed = False

    def _channel(self, topic: str, schema: dict[str, Any]) -> foxglove.Channel:
        ch = self._channels.get(topic)
        if ch is None:
            sdk_schema = foxglove.Schema(
                name=schema["title"], encoding="jsonschema", data=_encode.encode(schema)
            )
            ch = self._channels[topic] = foxglove.Channel(
                topic, schema=sdk_schema, message_encoding="json", context=self._context
            )
        return ch

    def write(self, batch: Iterable[Event]) -> None:
        if self._closed:
            return
        messages = self._encoder.messages
        for ev in batch:
            ns, out = messages(ev)
            for topic, schema, data in out:
                self._channel(topic, schema).log(data, log_time=ns)
                self.sent += 1
                if topic in LATCHED:
                    self._last[topic] = (data, ns)

    def resend(self, topic: str) -> None:
        """Send ``topic``'s last message again (a client subscribed to it)."""
        last = self._last.get(topic)
        if last is None or self._closed:
            return
        data, ns = last
        scene = self._encoder.scene
        if topic == "/tf":  # every robot, not only those that moved last
            data = scene.transforms(ns)
        elif topic == WORLD_TOPIC:  # every robot and object, as last told
            whole = {"t": ns / 1e9, "k": "world", "robots": scene.robots}
            data = _encode.encode({**whole, "objects": list(scene.objects.values())})
        self._channels[topic].log(data, log_time=ns)

    @property
    def refused(self) -> int:
        """Connections the guard refused (another site's page, a foreign Host)."""
        return self._guard.refused

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self._server.stop()
            self._guard.close()
