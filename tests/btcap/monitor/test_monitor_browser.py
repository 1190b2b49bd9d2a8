"""The monitor page in a real headless browser (Debian's chromium and chromium-driver,
driven by selenium), as a person would use it: open the page, run a mission, watch.

Skipped, saying why, only where chromium or chromedriver is missing. Set
``BTCAP_DOCS_SCREENSHOT=1`` to also write the simulated mission's screenshot to
``docs/monitor.png`` (the README's picture).
"""

from __future__ import annotations

import asyncio
import json
import os
import shutil
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import anyio
import pytest

from btcap import Leaf, Monitor, Parallel, Replay, Sequence, State, Tree
from btcap.bt.state import DONE
from btcap.monitor.server import MonitorServer
from btcap.sim.mission.scenario import load_scenario
from btcap.sim.running.runner import run_fast
from btcap.team.demo import ECHO, implementations
from btcap.team.runtime.agent import Agent, AgentConfig
from btcap.team.runtime.protocol import protocol_registry
from btcap.transports import InProcessNetwork

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
CHROMEDRIVER = shutil.which("chromedriver")
pytestmark = pytest.mark.skipif(
    CHROMIUM is None or CHROMEDRIVER is None,
    reason="needs Debian's chromium and chromium-driver (apt-get install chromium "
    "chromium-driver); .ci/run installs them",
)
DOCS = Path(__file__).parents[3] / "docs" / "monitor.png"
DYNAMIC = Path(__file__).parents[2] / "sim" / "data" / "dynamic.yaml"
#: Seconds the page may take to show what the test waits for (polled, not slept).
PAGE_S = 30.0

if CHROMIUM is not None and CHROMEDRIVER is not None:
    from selenium import webdriver
    from selenium.webdriver.chrome.options import Options
    from selenium.webdriver.chrome.service import Service
    from selenium.webdriver.common.by import By
    from selenium.webdriver.remote.webdriver import WebDriver
    from selenium.webdriver.support.wait import WebDriverWait


@pytest.fixture
def browser() -> Iterator[WebDriver]:
    options = Options()
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--window-size=1500,1000"):  # fmt: skip
        options.add_argument(arg)
    options.binary_location = str(CHROMIUM)
    driver = webdriver.Chrome(service=Service(str(CHROMEDRIVER)), options=options)
    driver.set_page_load_timeout(PAGE_S)
    try:
        yield driver
    finally:
        driver.quit()


#: What the page's picture and the server's must agree on.
PICTURE = ("robots", "runs", "auctions", "marks", "finished")
#: The page's picture (app.js keeps runs and auctions in Maps), as the server shapes it.
_PICTURE_JS = """return JSON.stringify({robots: S.robots, runs: [...S.runs.values()],
    auctions: [...S.auctions.values()], marks: S.marks, finished: S.finished ?? null});"""


def _page(driver: WebDriver) -> Any:
    """The picture the page built from the snapshot and the events it was sent."""
    return json.loads(driver.execute_script(_PICTURE_JS))


def _count(driver: WebDriver, css: str) -> int:
    return len(driver.find_elements(By.CSS_SELECTOR, css))


def _text(driver: WebDriver, css: str) -> str:
    return str(driver.find_element(By.CSS_SELECTOR, css).text)


def _closed_calmly(driver: WebDriver) -> bool:
    """The page shows its connection closed after the run finished (said on hover)."""
    return bool(driver.find_element(By.ID, "mode").get_attribute("title"))


async def _wait(driver: WebDriver, what: str, ok: Callable[[WebDriver], bool]) -> None:
    """Poll the page (in a thread: the monitor serves from this event loop meanwhile)."""

    def wait() -> None:
        WebDriverWait(driver, PAGE_S, poll_frequency=0.1).until(ok, f"the page to show {what}")

    await asyncio.to_thread(wait)


def _check_timeline_colours(driver: WebDriver) -> None:
    """Each capability has one colour in the timeline, in a legend of its own, and none is
    near a colour the trees' legend gives a node state."""
    js = """const fill = (e) => getComputedStyle(e).fill;
        const bg = (e) => getComputedStyle(e).backgroundColor;
        return [
          [...document.querySelectorAll('#legend i')].map(bg),
          [...document.querySelectorAll('.legend.caps span')].map(
            (s) => [s.dataset.capability, bg(s.querySelector('i'))]),
          [...document.querySelectorAll('.lane rect.bar')].map(
            (b) => [b.dataset.capability, fill(b)])];"""
    states, key, bars = driver.execute_script(js)
    legend = dict(key)
    assert len(legend) == len(key) >= 2  # a capability named once
    assert len(set(legend.values())) == len(legend)  # a colour each
    far = [min(_distance(c, s) for s in states) for c in legend.values()]
    assert min(far) >= 80, (legend, states)  # not only other values: other colours
    assert bars
    assert all(legend[cap] == fill for cap, fill in bars)


def _distance(a: str, b: str) -> float:
    """How far apart two CSS colours ``rgb(r, g, b)`` are in RGB."""
    rgb = [[float(v) for v in c[c.index("(") + 1 : -1].split(",")[:3]] for c in (a, b)]
    return float(sum((x - y) ** 2 for x, y in zip(*rgb, strict=True)) ** 0.5)


def _slots(driver: WebDriver) -> dict[str, str]:
    """How each robot's slot is drawn: robot -> the state it shows."""
    js = """return [...document.querySelectorAll('.tree-block.host')].map((b) =>
        [b.dataset.robot, b.querySelector('[data-node="slot"]').dataset.state]);"""
    return dict(driver.execute_script(js))


async def _screenshot(driver: WebDriver, *paths: Path) -> None:
    def shoot() -> None:
        height = driver.execute_script("return document.body.scrollHeight")
        driver.set_window_size(1500, min(2000, int(height) + 20))
        for path in paths:
            path.parent.mkdir(parents=True, exist_ok=True)
            assert driver.save_screenshot(str(path)), f"no screenshot written to {path}"

    await asyncio.to_thread(shoot)


async def test_the_page_shows_each_robot_and_a_capability_succeeding_live(
    browser: WebDriver, tmp_path: Path
) -> None:
    """The page is open before the mission starts: what it shows came over the stream."""
    net = InProcessNetwork(protocol_registry())
    cfg = AgentConfig(heartbeat_s=0.05, failure_timeout_s=5.0, auction_window_s=5.0)

    def agent(name: str, cost: float | None = None) -> Agent:
        impls = implementations(name, cost=cost, duration_s=0.5) if cost is not None else []
        return Agent(name, transport=net.transport(name), implementations=impls, config=cfg)

    with anyio.fail_after(90):
        async with (
            agent("base") as base,
            agent("scout", 1.0) as scout,
            agent("rover", 5.0) as rover,
            Monitor(port=0, title="browser test") as monitor,
        ):
            for a in (base, scout, rover):
                monitor.add_agent(a)
            await asyncio.to_thread(browser.get, monitor.url)
            await _wait(browser, "the live badge", lambda d: _count(d, ".mode.live") == 1)
            team = {"scout", "rover"}
            for _ in range(1000):  # the team forms (gossip), polled
                if base.repository.providers(ECHO.identity) == team <= base.team.alive():
                    break
                await asyncio.sleep(0.02)
            echoes = [ECHO.node_type()(f"echo_{k}", inputs={"value": k}) for k in (1, 2)]
            tree = base.mission(Parallel("mission", children=echoes))
            monitor.add_tree(tree, robot="base")
            final = await tree.run(20, until=lambda s: s in DONE)
            assert final is State.SUCCEEDED
            assert sorted(e.assignments[0] for e in echoes) == ["rover", "scout"]
            monitor.detach()  # the page keeps the mission's end, not its shutdown
            await _wait(
                browser,
                "a lane for each robot that worked",
                lambda d: (
                    _count(d, '.lane[data-robot="scout"]') == 1
                    and _count(d, '.lane[data-robot="rover"]') == 1
                ),
            )
            await _wait(
                browser,
                "both capability nodes succeeded",
                lambda d: _count(d, '.node.cap[data-state="succeeded"]') == 2,
            )
            assert _count(browser, "[data-auction] .bid.win") >= 2  # a busy robot may decline
            server = json.loads(json.dumps({k: monitor.snapshot()[k] for k in PICTURE}))
            await _wait(browser, "the same picture as the server's", lambda d: _page(d) == server)
            await _screenshot(browser, tmp_path / "monitor.png")
            await tree.shutdown()
            monitor.finish("succeeded", "mission succeeded after 1 s")
            await _wait(browser, "the finished badge", lambda d: _count(d, ".mode.finished") == 1)
            assert _text(browser, "#summary.succeeded") == "mission succeeded after 1 s"
            final = _page(browser)
    # The monitor has stopped: the page keeps the final picture and says how it ended.
    await _wait(browser, "the connection closed", _closed_calmly)
    assert _count(browser, ".mode.finished") == 1
    assert _count(browser, ".mode.down") == 0
    assert _page(browser) == final
    assert _count(browser, '.node.cap[data-state="succeeded"]') == 2
    assert (tmp_path / "monitor.png").stat().st_size > 10_000


async def test_a_simulated_mission_live_and_replayed(browser: WebDriver, tmp_path: Path) -> None:
    """The paper's robots with a failure, a join and a leave: the live page after the run,
    then its recording replayed and paused mid-mission (what docs/monitor.png shows)."""
    record = tmp_path / "dynamic.jsonl"
    robots = ("husky1", "husky2", "bebop1")
    with anyio.fail_after(90):
        async with Monitor(port=0, record=record, title="dynamic team") as monitor:
            result = await run_fast(load_scenario(DYNAMIC), monitor=monitor)
            assert result.completed
            await asyncio.to_thread(browser.get, monitor.url)
            await _wait(
                browser,
                "a lane per robot",
                lambda d: all(_count(d, f'.lane[data-robot="{r}"]') == 1 for r in robots),
            )
            assert _count(browser, '[data-node="mission"][data-state="succeeded"]') == 1
            assert _count(browser, ".card") == 4
            # after the run nobody hosts anything: no slot is drawn running (they are
            # ticked, waiting), and the robot that left is drawn gone, with its badge
            slots = {"operator": "idle", "husky1": "idle", "husky2": "idle", "bebop1": "gone"}
            await _wait(browser, f"the slots drawn {slots}", lambda d: _slots(d) == slots)
            assert _text(browser, '.tree-block.gone[data-robot="bebop1"] h3 .gone') == "· left"
            _check_timeline_colours(browser)
            await _screenshot(browser, tmp_path / "live.png")
            live = monitor.snapshot()["finished"]
            await _wait(browser, "the finished badge", lambda d: _count(d, ".mode.finished") == 1)
        replay = Replay.open(record)
        replay.playing = False
        replay.seek(replay.start + 0.3 * (replay.end - replay.start))
        server = MonitorServer(replay, "127.0.0.1", 0)
        await server.start()
        try:
            await asyncio.to_thread(browser.get, server.url)
            await _wait(browser, "the replay controls", lambda d: _count(d, "#replay[hidden]") == 0)
            await _wait(browser, "the running path", lambda d: _count(d, ".edge.active") > 0)
            assert _count(browser, ".lane text[fill]") >= 3  # marks: joins, the failure
            paths = [tmp_path / "replay.png"]
            if os.environ.get("BTCAP_DOCS_SCREENSHOT"):
                paths.append(DOCS)
            await _screenshot(browser, *paths)
            assert _count(browser, "#summary[hidden]") == 1  # not over yet
            # while husky1 is down its slot is drawn gone, and drawn again once it is back
            ups = [(e["t"], e["change"]) for e in replay.events
                   if e["k"] == "team" and e["robot"] == "husky1"]  # fmt: skip
            down = next(k for k, (_, change) in enumerate(ups) if change == "failed")
            replay.seek((ups[down][0] + ups[down + 1][0]) / 2)
            await _wait(browser, "husky1 gone", lambda d: _slots(d).get("husky1") == "gone")
            assert _text(browser, '.tree-block.gone[data-robot="husky1"] h3 .gone') == "· failed"
            replay.seek(ups[down + 1][0] + 1.0)
            await _wait(browser, "husky1 back", lambda d: _slots(d).get("husky1") != "gone")
            replay.seek(replay.end)  # the end: how the run ended, as the live page said
            await _wait(browser, "the finished badge", lambda d: _count(d, ".mode.finished") == 1)
            assert _text(browser, "#summary.succeeded") == live["summary"]
            replay.seek(replay.start)
            await _wait(browser, "the replay badge again", lambda d: _count(d, ".mode.replay") == 1)
        finally:
            await server.stop()
        # a replay stopped before its end is no finished run: the page says it lost it
        await _wait(browser, "the connection lost", lambda d: _count(d, ".mode.down") == 1)
    assert (tmp_path / "replay.png").stat().st_size > 10_000


async def test_robot_names_from_the_network_are_shown_as_text(browser: WebDriver) -> None:
    """Robot names come from peers: ``constructor``, ``__proto__`` and markup are valid
    names, and arriving over the stream they must show as any other robot's."""
    names = ["constructor", "__proto__", "<img src=x onerror=alert(1)>"]
    with anyio.fail_after(60):
        async with Monitor(port=0, title="names") as monitor:
            await asyncio.to_thread(browser.get, monitor.url)
            await _wait(browser, "the live badge", lambda d: _count(d, ".mode.live") == 1)
            for k, name in enumerate(names):
                monitor.emit({"t": 1.0, "k": "team", "robot": name, "change": "joined"})
                ex = f"base:mission/echo#{k}"
                monitor.emit({"t": 1.0, "k": "run", "phase": "start", "execution": ex,
                              "robot": name, "origin": "base", "node": "mission/echo",
                              "capability": "Echo"})  # fmt: skip
            auction = {"k": "auction", "id": "base#1", "execution": "base:mission/echo#0"}
            monitor.emit({**auction, "t": 1.0, "phase": "open", "auctioneer": "base",
                          "capability": "Echo", "node": "base:mission/echo",
                          "candidates": names, "why": "first request"})  # fmt: skip
            monitor.emit({**auction, "t": 2.0, "phase": "close", "winner": names[0],
                          "bids": [[n, 1.0] for n in names], "declined": {},
                          "reasons": {}})  # fmt: skip
            monitor.flush()
            await _wait(browser, "a card per robot", lambda d: _count(d, ".card") == 3)
            await _wait(browser, "every bid", lambda d: _count(d, ".bid") == 3)
            cards = browser.find_elements(By.CSS_SELECTOR, ".card h3 span:first-child")
            assert sorted(c.text for c in cards) == sorted(names)
            assert _count(browser, "img") == 0
            server = json.loads(json.dumps({k: monitor.snapshot()[k] for k in PICTURE}))
            await _wait(browser, "the same picture as the server's", lambda d: _page(d) == server)


async def test_identical_auctions_of_a_node_show_as_one_row_with_a_count(
    browser: WebDriver,
) -> None:
    """A task nobody takes is retried for minutes, another one's auctions in between, a
    bidder's cost changing each time: a row per task with its count and time span, folded
    alike on the page and the server."""
    nodes = ["operator:mission/loop_1/decontaminate", "operator:mission/loop_2/decontaminate"]
    with anyio.fail_after(60):
        async with Monitor(port=0, title="retries") as monitor:
            await asyncio.to_thread(browser.get, monitor.url)
            await _wait(browser, "the live badge", lambda d: _count(d, ".mode.live") == 1)
            for n in range(12):  # over the stream, in batches as they happen
                node, t = nodes[n % 2], 10.0 * n
                base = {"k": "auction", "id": f"operator#{n}", "execution": f"{node}#1"}
                declined = {"husky1": "busy", "spot1": "cannot"}
                if n % 4 == 3:
                    declined = dict(reversed(declined.items()))  # same, in another order
                monitor.emit({**base, "t": t, "phase": "open", "auctioneer": "operator",
                              "capability": "MoveToDecontamination", "node": node,
                              "candidates": ["husky1"],
                              "why": "retry: nobody took it last time"})  # fmt: skip
                cost = 300.0 - n  # kept out: not below the reserve
                reasons = {**declined, "bebop1": f"bid {cost:g} not below {cost / 2:g}"}
                monitor.emit({**base, "t": t + 0.5, "phase": "close",
                              "bids": [["bebop1", cost]], "declined": declined,
                              "reasons": reasons, "winner": None})  # fmt: skip
                monitor.flush()
            await _wait(browser, "two rows", lambda d: _count(d, "tr[data-auction]") == 2)
            rows = browser.execute_script(
                """return [...document.querySelectorAll("tr[data-auction]")].map((r) =>
                    [r.dataset.auction, r.querySelector(".count").textContent,
                     r.querySelector("td.num").textContent]);"""
            )
            times, dash = "\u00d7", "\u2013"  # the page: "x6", "10.0-110" in its signs
            assert rows == [
                ["operator#11", f"{times}6", f"10.0{dash}110"],
                ["operator#10", f"{times}6", f"0.0{dash}100"],
            ]
            server = json.loads(json.dumps({k: monitor.snapshot()[k] for k in PICTURE}))
            assert [a["count"] for a in server["auctions"]] == [6, 6]
            await _wait(browser, "the same picture as the server's", lambda d: _page(d) == server)


async def test_re_evaluations_that_changed_nothing_are_hidden_unless_asked_for(
    browser: WebDriver,
) -> None:
    """Every running task is re-auctioned now and then and nearly always stays where it is:
    "informative only" (the default) hides those rows and says how many it hides."""
    nodes = ["operator:mission/identify", "operator:mission/clean"]
    with anyio.fail_after(60):
        async with Monitor(port=0, title="re-evaluations") as monitor:
            await asyncio.to_thread(browser.get, monitor.url)
            await _wait(browser, "the live badge", lambda d: _count(d, ".mode.live") == 1)

            def auction(n: int, node: str, why: str, winner: str | None, cost: float) -> None:
                base = {"k": "auction", "id": f"operator#{n}", "execution": f"{node}#1"}
                monitor.emit({**base, "t": float(n), "phase": "open", "auctioneer": "operator",
                              "capability": "Identify", "node": node,
                              "candidates": ["husky1", "husky2"], "why": why})  # fmt: skip
                reasons = {} if winner else {"husky1": f"bid {cost:g} not below {cost / 2:g}"}
                monitor.emit({**base, "t": n + 0.5, "phase": "close",
                              "bids": [["husky1", cost]], "declined": {"husky2": "busy"},
                              "reasons": reasons, "winner": winner})  # fmt: skip

            auction(1, nodes[0], "first request", "husky1", 300.0)
            auction(2, nodes[1], "first request", "husky1", 200.0)
            for n in range(3, 9):  # the first task stays on husky1, its cost falling
                auction(n, nodes[0], "re-evaluation: may move from husky1", None, 300.0 - n)
            auction(9, nodes[1], "re-evaluation: may move from husky1", None, 190.0)
            auction(10, nodes[1], "re-evaluation: husky2 joined; husky1 runs it", "husky2", 9.0)
            monitor.flush()

            def rows(d: WebDriver) -> list[str]:
                js = """return [...document.querySelectorAll('tr[data-auction]')].map(
                    (r) => r.dataset.auction);"""
                return list(d.execute_script(js))

            shown = ["operator#10", "operator#2", "operator#1"]
            await _wait(browser, "the informative rows", lambda d: rows(d) == shown)
            assert _text(browser, "#hidden") == "2 hidden"  # #8 (x6) and #9
            browser.find_element(By.ID, "informative").click()
            every = ["operator#10", "operator#9", "operator#8", "operator#2", "operator#1"]
            await _wait(browser, "every row", lambda d: rows(d) == every)
            assert _text(browser, '[data-auction="operator#8"] .count') == "\u00d76"
            assert _text(browser, "#hidden") == ""
            browser.find_element(By.ID, "informative").click()
            await _wait(browser, "the informative rows again", lambda d: rows(d) == shown)


class _Step(Leaf):
    def on_tick(self) -> State:
        return State.SUCCEEDED


async def test_a_tree_wider_than_its_panel_is_fitted_or_shown_at_100_percent(
    browser: WebDriver,
) -> None:
    tree = Tree(Sequence("wide", children=[_Step(f"step_{k}") for k in range(40)]))
    tree.setup()
    with anyio.fail_after(60):
        async with Monitor(port=0, title="wide") as monitor:
            monitor.add_tree(tree, robot="ada")
            await asyncio.to_thread(browser.get, monitor.url)
            svg = '#trees svg[data-tree="wide"]'
            await _wait(browser, "the tree", lambda d: _count(d, svg) == 1)

            def sizes(d: WebDriver) -> tuple[float, float, float]:
                """(drawn width, natural width, the panel's width)"""
                js = """const s = document.querySelector(arguments[0]);
                    return [s.getBoundingClientRect().width, s.viewBox.baseVal.width,
                            document.getElementById('trees').clientWidth];"""
                w, natural, panel = d.execute_script(js, svg)
                return float(w), float(natural), float(panel)

            def scroll_width(d: WebDriver) -> float:
                scroll = d.find_element(By.CSS_SELECTOR, ".tree-scroll")
                return float(d.execute_script("return arguments[0].scrollWidth", scroll))

            drawn, natural, panel = sizes(browser)
            assert natural > 2 * panel  # 40 leaves: far wider than the panel
            # fitted by default, but not below 80 % (its text would be too small to read):
            # what does not fit then scrolls
            assert drawn == pytest.approx(0.8 * natural, abs=1)
            assert scroll_width(browser) > panel
            assert _text(browser, ".tree-block .zoomed") == "· 80 %"
            browser.find_element(By.ID, "fit").click()  # at 100 %, with a scroll bar
            await _wait(browser, "the tree at 100 %", lambda d: sizes(d)[0] == sizes(d)[1])
            assert scroll_width(browser) > panel
            assert _count(browser, ".tree-block .zoomed") == 0
            browser.find_element(By.ID, "fit").click()
            await _wait(browser, "the tree fitted again", lambda d: sizes(d)[0] < natural)
            # one just wider than the panel is fitted whole
            narrow = Tree(Sequence("narrow", children=[_Step(f"s_{k}") for k in range(7)]))
            narrow.setup()
            monitor.add_tree(narrow, robot="bob")
            monitor.flush()
            svg = '#trees svg[data-tree="narrow"]'
            await _wait(browser, "the narrow tree", lambda d: _count(d, svg) == 1)
            drawn, natural, panel = sizes(browser)
            assert natural > panel > 0.8 * natural  # the test's window: 1500 px wide
            assert drawn <= panel
    await tree.shutdown()
    await narrow.shutdown()
