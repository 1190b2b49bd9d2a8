"""Screenshots of a btcap MCAP recording in Foxglove Studio, taken in headless Chromium.

Foxglove Studio's core, ``@foxglove/studio-base`` 1.48.0 on npm, ships its whole app
built by webpack (``assets/index.js``, React and ReactDOM left to the page). This script
writes a page of a few lines that renders its ``App`` with the MCAP file as a remote
file (``?ds=remote-file``) and the layout ``examples/foxglove/btcap.json`` translated
to Studio 1.48's layout format, serves it on loopback (with HTTP range requests, which
Studio needs), drives Debian's chromium through chromedriver (Selenium, a dev
dependency) and writes a PNG. It needs npm packages, so neither CI nor the tests run it:

    mkdir -p /tmp/foxweb && cd /tmp/foxweb && npm install \\
        @foxglove/studio-base@1.48.0 react@17.0.2 react-dom@17.0.2
    btcap run full-team --fast --record /tmp/run.mcap
    python docs/hooks/foxglove_screenshot.py /tmp/run.mcap --npm /tmp/foxweb --at 600 \\
        --size 1600,1100 --out docs/foxglove-full-team.png --panel docs/foxglove-cave.png
"""

from __future__ import annotations

import argparse
import http.server
import json
import re
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
LAYOUT = ROOT / "examples" / "foxglove" / "btcap.json"
PANEL_TYPES = {"ThreeDee": "3D", "Log": "RosOut"}  # the rest keep their names
TYPES = {
    ".html": "text/html",
    ".js": "application/javascript",
    ".json": "application/json",
    ".wasm": "application/wasm",
    ".png": "image/png",
    ".ttf": "font/ttf",
    ".mcap": "application/octet-stream",
}

PAGE = """<!doctype html>
<html><head><meta charset="utf-8"><title>btcap in Foxglove Studio</title>
<style>html, body, #root { margin: 0; width: 100%; height: 100%; }</style>
</head><body><div id="root"></div>
<script src="/react/umd/react.production.min.js"></script>
<script src="/react-dom/umd/react-dom.production.min.js"></script>
<script>window["react"] = window.React; window["react-dom"] = window.ReactDOM;</script>
<script src="/studio/index.js"></script>
<script>
(async () => {
  try {
    await initI18n();
    const data = await (await fetch("/layout.json")).json();
    const values = new Map();
    const layouts = new Map([["btcap", {id: "btcap", name: "btcap",
      permission: "CREATOR_WRITE", baseline: {data, savedAt: undefined},
      working: undefined, syncInfo: undefined}]]);
    ReactDOM.render(React.createElement(App, {
      deepLinks: [window.location.href],
      dataSources: [new RemoteDataSourceFactory()],
      extensionLoaders: [],
      enableGlobalCss: true,
      appConfiguration: {get: (k) => values.get(k), set: async (k, v) => { values.set(k, v); },
        addChangeListener() {}, removeChangeListener() {}},
      layoutStorage: {list: async () => [...layouts.values()],
        get: async (_ns, id) => layouts.get(id),
        put: async (_ns, layout) => { layouts.set(layout.id, layout); return layout; },
        delete: async (_ns, id) => { layouts.delete(id); }, importLayouts: async () => {}},
    }), document.getElementById("root"));
  } catch (e) { window.btcapError = String(e && e.stack || e); }
})();
</script></body></html>
"""


def studio_layout(layout: dict[str, Any], speed: float = 1.0) -> dict[str, Any]:
    """The layout file (the Foxglove SDK's format) as Studio 1.48's LayoutData: panels
    keyed ``Type!id`` with their config, and a binary mosaic tree of splits."""
    config_by_id: dict[str, Any] = {}

    def node(item: dict[str, Any]) -> Any:
        content = item.get("content", item)
        if "items" in content:
            return split(content["direction"], content["items"])
        kind = PANEL_TYPES.get(content["panelType"], content["panelType"])
        panel_id = f"{kind}!btcap{len(config_by_id)}"
        config = dict(content.get("config", {}))
        if content.get("title"):
            config["foxglovePanelTitle"] = content["title"]
        config_by_id[panel_id] = config
        return panel_id

    def split(direction: str, items: list[dict[str, Any]]) -> Any:
        if len(items) == 1:
            return node(items[0])
        first = items[0].get("proportion", 1)
        rest = sum(item.get("proportion", 1) for item in items[1:])
        return {
            "direction": direction,
            "first": node(items[0]),
            "second": split(direction, items[1:]),
            "splitPercentage": 100 * first / (first + rest),
        }

    tree = node(layout)
    return {
        "configById": config_by_id,
        "layout": tree,
        "globalVariables": {},
        "userNodes": {},
        "playbackConfig": {"speed": speed},
    }


class _Files(http.server.BaseHTTPRequestHandler):
    routes: dict[str, Path] = {}
    blobs: dict[str, bytes] = {}

    def log_message(self, format: str, *args: Any) -> None:
        pass

    def do_GET(self) -> None:
        path = self.path.split("?", 1)[0]
        path = "/index.html" if path == "/" else path
        body = self.blobs.get(path)
        if body is None:
            prefix, _, rest = path.lstrip("/").partition("/")
            base = self.routes.get(prefix)
            file = (base / rest).resolve() if base else None
            if file is None or base is None or not file.is_relative_to(base) or not file.is_file():
                self.send_error(404)
                return
            body = file.read_bytes()
        start, end = 0, len(body) - 1
        match = re.fullmatch(r"bytes=(\d+)-(\d*)", self.headers.get("range", ""))
        if match:
            start = int(match[1])
            end = min(int(match[2]) if match[2] else end, end)
        self.send_response(206 if match else 200)
        self.send_header("content-type", TYPES.get(Path(path).suffix, "application/octet-stream"))
        self.send_header("accept-ranges", "bytes")
        self.send_header("access-control-allow-origin", "*")
        self.send_header("access-control-expose-headers", "accept-ranges, content-range")
        if match:
            self.send_header("content-range", f"bytes {start}-{end}/{len(body)}")
        self.send_header("content-length", str(end + 1 - start))
        self.end_headers()
        self.wfile.write(body[start : end + 1])


@contextmanager
def serve(npm: Path, mcap: Path, speed: float = 1.0) -> Iterator[str]:
    """Serves the page, Studio's assets, React and the recording on a free loopback port."""
    modules = npm / "node_modules"
    routes = {
        "studio": (modules / "@foxglove" / "studio-base" / "assets").resolve(),
        "react": (modules / "react").resolve(),
        "react-dom": (modules / "react-dom").resolve(),
    }
    blobs = {
        "/index.html": PAGE.encode(),
        "/layout.json": json.dumps(studio_layout(json.loads(LAYOUT.read_text()), speed)).encode(),
        "/run.mcap": mcap.read_bytes(),
    }
    handler = type("Files", (_Files,), {"routes": routes, "blobs": blobs})
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}"
    finally:
        server.shutdown()
        server.server_close()
        thread.join()


def _clock(text: str) -> float:
    """Seconds since the epoch's midnight in Studio's time display ("12:10:00.000 AM GMT")."""
    match = re.match(r"(\d+):(\d+):(\d+(?:\.\d+)?) (AM|PM)", text.strip())
    if match is None:
        return -1.0
    hours = int(match[1]) % 12 + (12 if match[4] == "PM" else 0)
    return hours * 3600 + int(match[2]) * 60 + float(match[3])


_TO_THE_END = """for (const el of document.querySelectorAll('[data-testid*=" RosOut!"] *'))
    if (el.scrollHeight > el.clientHeight) el.scrollTop = el.scrollHeight;"""


def _small(path: Path) -> None:
    """Rewrites a PNG with a palette of 256 colours: a third of the bytes, the same look."""
    from PIL import Image

    with Image.open(path) as image:
        small = image.convert("RGB").quantize(256)
    small.save(path, optimize=True)


def shoot(
    driver: Any, page: str, at: float, out: Path, panel: Path | None, timeout: float
) -> float:
    """Opens ``page``, plays the recording to ``at`` seconds (so the Log panel holds every
    line before it), pauses and writes the screenshot, and the 3D panel's alone to
    ``panel``; returns the time they show."""
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.wait import WebDriverWait

    wait = WebDriverWait(driver, timeout, poll_frequency=0.5)
    driver.get(page)

    def button(title: str) -> Any:
        found = driver.find_elements(By.CSS_SELECTOR, f'button[title="{title}"]')
        return found[0] if found else False

    def shown(_: Any) -> float | bool:
        error = driver.execute_script("return window.btcapError")
        if error:
            raise SystemExit(f"the page failed: {error}")
        found = driver.find_elements(By.CSS_SELECTOR, '[data-testid="PlaybackTime-text"] input')
        if not found:
            return False
        now = _clock(found[0].get_attribute("value") or found[0].text)
        return now if now >= 0 else False

    wait.until(shown)
    wait.until(lambda _: button("Play")).click()
    wait.until(lambda d: (shown(d) or 0) >= at)
    wait.until(lambda _: button("Pause")).click()
    for dismiss in driver.find_elements(By.CSS_SELECTOR, 'button[aria-label="Dismiss"]'):
        dismiss.click()
    driver.execute_script(_TO_THE_END)
    time.sleep(3)  # lets the paused frame draw: nothing on the page says it has
    now = float(shown(driver))
    driver.save_screenshot(str(out))
    _small(out)
    if panel is not None:
        driver.find_element(By.CSS_SELECTOR, '[data-testid*=" 3D!"]').screenshot(str(panel))
        _small(panel)
    return now


def main() -> None:
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("mcap", type=Path)
    parser.add_argument("--npm", type=Path, required=True, help="where npm installed Studio")
    parser.add_argument("--out", type=Path, required=True, help="the PNG to write")
    parser.add_argument("--panel", type=Path, help="a PNG of the 3D panel alone")
    parser.add_argument("--at", type=float, default=600.0, help="seconds into the run")
    parser.add_argument("--speed", type=float, default=20.0, help="playback speed to get there")
    parser.add_argument("--size", default="1600,1000", help="window size, pixels")
    parser.add_argument("--timeout", type=float, default=300.0, help="seconds to give up after")
    args = parser.parse_args()
    options = webdriver.ChromeOptions()
    options.binary_location = "/usr/bin/chromium"
    for flag in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage"):
        options.add_argument(flag)
    options.add_argument(f"--window-size={args.size}")
    with serve(args.npm, args.mcap, args.speed) as url:
        page = f"{url}/?ds=remote-file&ds.url={url}/run.mcap&layoutId=btcap"
        driver = webdriver.Chrome(options=options, service=Service("/usr/bin/chromedriver"))
        try:
            now = shoot(driver, page, args.at, args.out, args.panel, args.timeout)
        finally:
            driver.quit()
    print(f"wrote {args.out}{' and ' + str(args.panel) if args.panel else ''}: at {now:.1f} s")


if __name__ == "__main__":
    main()
