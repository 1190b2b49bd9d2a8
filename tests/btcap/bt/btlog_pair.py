"""One tree's run logged twice: by btcap's BtlogRecorder and by BehaviorTree.CPP's own
FileLogger (behaviortreepy), on the same XML and the same scripted ticks."""

from __future__ import annotations

import struct
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import behaviortreepy as bt
from btcpp_oracle import BtcapRun, BtcppRun

from btcap.bt.files.btlog import HEADER, Btlog, BtlogRecorder, read_btlog


def run_both(
    xml: str, scripts: dict[str, str], ticks: int, tmp: Path, once: bool = False
) -> tuple[Btlog, Btlog]:
    """Tick both ``ticks`` times, halt both, and read both files back."""
    return run_many([(xml, scripts)], ticks, tmp, once)[0]


def run_many(
    cases: list[tuple[str, dict[str, str]]], ticks: int, tmp: Path, once: bool = False
) -> list[tuple[Btlog, Btlog]]:
    """:func:`run_both` for many trees, waiting for BehaviorTree.CPP's files only once."""
    loggers = []
    files = []
    for k, (xml, scripts) in enumerate(cases):
        mine, theirs = BtcapRun(xml, scripts, once), BtcppRun(xml, scripts, once)
        # The oracle's own watch replaces the profile hook the recorder uses: drop it
        # here (these runs compare the logs, not the documented differences it watches).
        del mine.tree.tick
        mine.tree.setup()
        ours, cpp = tmp / f"btcap{k}.btlog", tmp / f"btcpp{k}.btlog"
        with BtlogRecorder(mine.tree, ours):
            loggers.append((bt.FileLogger(theirs.tree, str(cpp)), theirs))
            for _ in range(ticks):
                mine.tick()
                theirs.tick()
            mine.halt()
            theirs.halt()
        files.append((ours, cpp))
    settled(files)
    loggers.clear()
    return [(read_btlog(ours), read_btlog(cpp)) for ours, cpp in files]


def run_plans(
    cases: list[tuple[str, dict[str, str], str]], tmp: Path
) -> list[tuple[Btlog, Btlog] | None]:
    """Each tree played by its plan in both, ``t`` a tick, ``h`` btcap's ``tree.reset()``
    and BehaviorTree.CPP's ``haltTree`` (each logged as the latter); None for a tree whose
    ticks give other results after a halt (a documented difference, not the log's)."""
    loggers = []
    files = []
    for k, (xml, scripts, plan) in enumerate(cases):
        mine, theirs = BtcapRun(xml, scripts), BtcppRun(xml, scripts)
        del mine.tree.tick  # as in run_many
        mine.tree.setup()
        ours, cpp = tmp / f"plan{k}.btlog", tmp / f"plan{k}-btcpp.btlog"
        same = True
        with BtlogRecorder(mine.tree, ours):
            loggers.append((bt.FileLogger(theirs.tree, str(cpp)), theirs))
            for step in plan:
                if step == "t":
                    same = same and mine.tick() == theirs.tick()
                else:
                    mine.reset()
                    theirs.halt()
        files.append((ours, cpp) if same else None)
    settled([f for f in files if f is not None])
    loggers.clear()
    return [None if f is None else (read_btlog(f[0]), read_btlog(f[1])) for f in files]


def settled(files: list[tuple[Path, Path]], quiet: int = 3, limit_s: float = 30.0) -> None:
    """Wait until BehaviorTree.CPP's writer threads have written what they were given.

    Its logger writes from a thread every 10 ms; 4.8's destructor can end that thread
    before it wrote anything (fixed in later releases), so the loggers stay alive until
    each of their files holds at least as many records as btcap's and no file grew for
    ``quiet`` checks in a row. At the limit the files are compared as they are.
    """
    deadline = time.monotonic() + limit_s
    sizes: list[int] = []
    same = 0
    while same < quiet and time.monotonic() < deadline:
        time.sleep(0.03)
        now = [cpp.stat().st_size for _, cpp in files]
        full = all(
            size >= _expected(ours, cpp) for size, (ours, cpp) in zip(now, files, strict=True)
        )
        same = same + 1 if full and now == sizes else 0
        sizes = now


def _expected(ours: Path, cpp: Path) -> int:
    """The size of ``cpp`` with as many records as ``ours`` (its own XML's length)."""
    head = cpp.read_bytes()[: len(HEADER) + 4]
    if len(head) < len(HEADER) + 4:
        return 1 << 62
    xml = struct.unpack_from("<i", head, len(HEADER))[0]
    records = (ours.stat().st_size - len(HEADER) - 12 - _xml_size(ours)) // 9
    return len(HEADER) + 12 + xml + 9 * records


def _xml_size(path: Path) -> int:
    return int(struct.unpack_from("<i", path.read_bytes(), len(HEADER))[0])


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
