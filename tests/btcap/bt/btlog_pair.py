"""One tree's run logged twice: by btcap's BtlogRecorder and by BehaviorTree.CPP's own
FileLogger (behaviortreepy), on the same XML and the same scripted ticks."""

from __future__ import annotations

import time
import xml.etree.ElementTree as ET
from pathlib import Path

import behaviortreepy as bt
from btcpp_oracle import BtcapRun, BtcppRun

from btcap.bt.files.btlog import Btlog, BtlogRecorder, read_btlog


def run_both(
    xml: str, scripts: dict[str, str], ticks: int, tmp: Path, once: bool = False
) -> tuple[Btlog, Btlog]:
    """Tick both ``ticks`` times, halt both, and read both files back."""
    mine, theirs = BtcapRun(xml, scripts, once), BtcppRun(xml, scripts, once)
    # The oracle's own watch replaces the profile hook the recorder uses: drop it here
    # (these runs compare the logs, not the documented differences it looks for).
    del mine.tree.tick
    mine.tree.setup()
    ours, cpp = tmp / "btcap.btlog", tmp / "btcpp.btlog"
    with BtlogRecorder(mine.tree, ours):
        logger = bt.FileLogger(theirs.tree, str(cpp))
        for _ in range(ticks):
            mine.tick()
            theirs.tick()
        mine.halt()
        theirs.halt()
        settled(cpp)
        del logger
    return read_btlog(ours), read_btlog(cpp)


def settled(path: Path, quiet: int = 3, limit_s: float = 20.0) -> None:
    """Wait until BehaviorTree.CPP's writer thread has written everything queued.

    It writes every 10 ms while the logger lives; 4.8's destructor can end the thread
    before it wrote anything (fixed in later releases), so the test waits for the file to
    stop growing for ``quiet`` checks in a row instead.
    """
    deadline = time.monotonic() + limit_s
    size, same = -1, 0
    while same < quiet:
        if time.monotonic() > deadline:
            raise AssertionError(f"{path} still growing after {limit_s} s")
        time.sleep(0.03)
        now = path.stat().st_size
        same = same + 1 if now == size else 0
        size = now


def elements(xml: str) -> list[tuple[str, dict[str, str]]]:
    """Every element of the tree part (not the models) with its attributes, in order."""
    root = ET.fromstring(xml)
    return [(e.tag, dict(e.attrib)) for t in root.findall("BehaviorTree") for e in t.iter()]


def models(xml: str) -> dict[str, str]:
    """Model ID to kind (Action, Condition, Control, Decorator, SubTree)."""
    found = ET.fromstring(xml).find("TreeNodesModel")
    return {} if found is None else {m.attrib["ID"]: m.tag for m in found}


def changes(log: Btlog) -> list[tuple[int, int]]:
    return [(uid, status) for _, uid, status in log.transitions]
