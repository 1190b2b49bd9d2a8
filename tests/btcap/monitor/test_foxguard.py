"""The live Foxglove server keeps the monitor page's rules for who may connect, which
the Foxglove SDK's own server does not: on loopback a ``Host`` of this machine only (DNS
rebinding), and no WebSocket opened by another web site's page (its ``Origin``);
programs, this machine's pages, Foxglove's web app and desktop apps are served."""

from __future__ import annotations

import asyncio
import contextlib
import functools
import http.server
import shutil
import socket
import threading
from pathlib import Path

import anyio
import pytest

from btcap.monitor.foxguard import FoxgloveGuard, refusal
from btcap.monitor.foxlive import FoxgloveLive

websockets = pytest.importorskip("websockets")
SUBPROTOCOL = "foxglove.sdk.v1"


def _head(host: str, origin: str | None = None) -> bytes:
    lines = ["GET / HTTP/1.1", f"Host: {host}", "Upgrade: websocket"]
    lines += [f"Origin: {origin}"] if origin is not None else []
    return ("\r\n".join(lines) + "\r\n\r\n").encode()


@pytest.mark.parametrize(
    ("host", "origin", "served"),
    [
        ("127.0.0.1:8765", None, True),  # a program (desktop apps send none or their own)
        ("localhost:8765", None, True),
        ("[::1]:8765", None, True),
        ("LOCALHOST:8765", None, True),
        ("evil.example:8765", None, False),  # DNS rebinding: a site's name for 127.0.0.1
        ("127.0.0.1:8765", "http://evil.example", False),  # another site's page
        ("127.0.0.1:8765", "https://evil.example:443", False),
        ("127.0.0.1:8765", "null", True),  # a file: page (a desktop app's; a sandboxed frame's)
        ("127.0.0.1:8765", "https://app.foxglove.dev", True),  # Foxglove's web app
        ("127.0.0.1:8765", "http://localhost:3000", True),  # a page served here
        ("127.0.0.1:8765", "http://[::1]:8080", True),
        ("127.0.0.1:8765", "file://", True),  # a desktop app's page
        ("127.0.0.1:8765", "app://lichtblick", True),
    ],
)
def test_who_is_served_on_loopback(host: str, origin: str | None, served: bool) -> None:
    assert (refusal(_head(host, origin), loopback=True) is None) == served


def test_off_loopback_any_host_but_not_any_page() -> None:
    """Bound to 0.0.0.0 (said as a warning), a robot's name for it is fine; another
    site's page still is not."""
    assert refusal(_head("robot7.lan:8765"), loopback=False) is None
    assert refusal(_head("robot7.lan:8765", "http://evil.example"), loopback=False)


async def test_another_sites_page_is_refused_and_programs_are_served() -> None:
    with anyio.fail_after(30):
        live = FoxgloveLive("127.0.0.1", 0)
        url = f"ws://127.0.0.1:{live.port}"
        try:
            for headers in (
                {"Origin": "http://evil.example"},
                {"Host": f"evil.example:{live.port}"},
            ):
                with pytest.raises(websockets.InvalidStatus, match="HTTP 403"):
                    async with websockets.connect(
                        url, subprotocols=[SUBPROTOCOL], additional_headers=headers
                    ):
                        pass
            assert live.refused == 2
            for origin in (None, "https://app.foxglove.dev"):
                async with websockets.connect(url, subprotocols=[SUBPROTOCOL], origin=origin) as ws:
                    assert '"op":"serverInfo"' in await ws.recv()
        finally:
            live.close()
    assert not [t for t in threading.enumerate() if t.name == "foxglove-guard"]


_PAGE = b"""<!doctype html><title>pending</title><script>
const ws = new WebSocket("ws://127.0.0.1:" + location.hash.slice(1), "foxglove.sdk.v1");
ws.onmessage = () => { document.title = "served"; };
ws.onerror = () => { document.title = "refused"; };
</script>"""


@pytest.mark.slow
@pytest.mark.skipif(
    shutil.which("chromium") is None or shutil.which("chromedriver") is None,
    reason="needs Debian's chromium and chromium-driver (as test_monitor_browser.py)",
)
async def test_a_browser_page_of_another_site_is_refused(tmp_path: Path) -> None:
    """In headless Chromium, a page of ``evil.example`` (resolved to this machine, as a
    site would have it by DNS rebinding or a WebSocket to 127.0.0.1) is refused; a page
    served here is served."""
    from selenium import webdriver
    from selenium.webdriver.chrome.options import Options
    from selenium.webdriver.chrome.service import Service
    from selenium.webdriver.support.wait import WebDriverWait

    (tmp_path / "page.html").write_bytes(_PAGE)
    handler = functools.partial(http.server.SimpleHTTPRequestHandler, directory=str(tmp_path))
    pages = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=pages.serve_forever, daemon=True).start()
    options = Options()
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--host-resolver-rules=MAP evil.example 127.0.0.1"):  # fmt: skip
        options.add_argument(arg)
    options.binary_location = str(shutil.which("chromium"))
    driver = webdriver.Chrome(service=Service(str(shutil.which("chromedriver"))), options=options)
    live = FoxgloveLive("127.0.0.1", 0)
    seen = {}
    try:

        def visit(site: str) -> str:
            driver.get(f"http://{site}:{pages.server_port}/page.html#{live.port}")
            WebDriverWait(driver, 30, poll_frequency=0.1).until(
                lambda d: d.title != "pending", f"{site}'s page to connect or fail"
            )
            return str(driver.title)

        with anyio.fail_after(90):
            for site in ("evil.example", "localhost"):
                seen[site] = await anyio.to_thread.run_sync(visit, site)
    finally:
        live.close()
        driver.quit()
        pages.shutdown()
        pages.server_close()
    assert seen == {"evil.example": "refused", "localhost": "served"}
    assert live.refused == 1


async def test_silent_connections_cannot_pile_up(monkeypatch: pytest.MonkeyPatch) -> None:
    """Clients that connect and send no request head are held at most PENDING_MAX at a
    time, the oldest closed for a newer one (they would hold the run's descriptors for
    HEAD_S each, without bound); the newer ones are still served."""
    from btcap.monitor import foxguard

    monkeypatch.setattr(foxguard, "HEAD_S", 3600.0)  # never the timeout that closes them
    monkeypatch.setattr(foxguard, "PENDING_MAX", 3)
    with anyio.fail_after(30):
        live = FoxgloveLive("127.0.0.1", 0)
        streams = []
        try:
            for _ in range(4):  # accepted in this order (the listen queue's)
                streams.append(await asyncio.open_connection("127.0.0.1", live.port))
            assert await streams[0][0].read() == b""  # the oldest, closed by the guard
            for reader, writer in streams[1:]:
                writer.write(_head(f"127.0.0.1:{live.port}", None)[:-2] + _UPGRADE)
                assert (await reader.readline()).startswith(b"HTTP/1.1 101")
        finally:
            for _, writer in streams:
                writer.close()
            live.close()


_UPGRADE = (
    b"Connection: Upgrade\r\nSec-WebSocket-Version: 13\r\n"
    b"Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
    b"Sec-WebSocket-Protocol: foxglove.sdk.v1\r\n\r\n"
)


async def test_the_sdks_own_port_is_not_on_127_0_0_1() -> None:
    """A page may open a WebSocket to any loopback port, and scan 127.0.0.1's for one that
    answers: the SDK's own server (no Host or Origin rules) must not be there to find."""
    with anyio.fail_after(30):
        live = FoxgloveLive("127.0.0.1", 0)
        try:
            with pytest.raises(ConnectionRefusedError):
                async with websockets.connect(
                    f"ws://127.0.0.1:{live._server.port}",
                    subprotocols=[SUBPROTOCOL],
                    origin="http://evil.example",
                ):
                    pass
            url = f"ws://127.0.0.1:{live.port}"
            async with websockets.connect(url, subprotocols=[SUBPROTOCOL]) as ws:
                assert '"op":"serverInfo"' in await ws.recv()  # through the guard
        finally:
            live.close()


def test_a_connection_accepted_as_the_guard_closes_is_closed_too() -> None:
    """A connection the guard accepted just before closing (its task not started) was
    left open, its client waiting on it and its descriptor held."""
    for _ in range(10):
        guard = FoxgloveGuard("127.0.0.1", 0, 1)
        with socket.create_connection(("127.0.0.1", guard.port)) as client:
            guard.close()
            client.settimeout(10.0)  # a bound: closed, it answers at once
            with contextlib.suppress(ConnectionResetError):  # not accepted yet: reset
                assert client.recv(1) == b""
