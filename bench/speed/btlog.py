"""The cost of a ``.btlog`` per logged status change: btcap's BtlogRecorder vs
BehaviorTree.CPP 4.8's own FileLogger through ``behaviortreepy``, in one run.

The tree, the same XML in both: a Sequence of 50 ``Fallback(AlwaysFailure,
AlwaysSuccess)``, so one tick makes 353 status changes (each Fallback turns RUNNING, its
children give their results and are reset, then the Sequence resets the Fallbacks and
the tree its root). Four tick functions take turns (:func:`btcap.bench.speed.tick.time_shape`):
btcap without and with a recorder, BehaviorTree.CPP without and with its logger.

Reported: the extra time per status change (logged tick minus plain tick, median, over
the changes in a tick), wall and CPU of the ticking thread, and their ratio. BehaviorTree.CPP
writes the file from a second thread, so the ticking thread's CPU leaves that work
out; btcap writes from the ticking thread (about every 10 ms), so its figure includes
it. ``python -m btcap.bench btlog [--quick]``.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import btcap
from btcap.bench.common import percentiles, write_result
from btcap.bench.speed.tick import time_shape
from btcap.bench.speed.tick_peers import load_average
from btcap.bt.files import loads_tree
from btcap.bt.files.btlog import BtlogRecorder, read_btlog

FALLBACKS = 50
XML = (
    '<root BTCPP_format="4"><BehaviorTree ID="Main"><Sequence>'
    + "<Fallback><AlwaysFailure/><AlwaysSuccess/></Fallback>" * FALLBACKS
    + "</Sequence></BehaviorTree></root>"
)


def _btcpp() -> Any:
    try:
        import behaviortreepy as bt  # type: ignore[import-untyped,import-not-found,unused-ignore]
    except ImportError:
        return None
    return bt


def run(quick: bool = False) -> dict[str, Any]:
    warmup, count = (20, 200) if quick else (100, 1_000)
    load_start = load_average()
    folder = Path(tempfile.mkdtemp(prefix="btcap-btlog-bench-"))
    plain = loads_tree(XML, "xml")
    logged = loads_tree(XML, "xml")
    recorder = BtlogRecorder(logged, folder / "btcap.btlog")
    assert logged.tick() is btcap.SUCCEEDED
    per_tick = recorder.transitions
    ticks: dict[str, Callable[[], object]] = {"btcap": plain.tick, "btcap_logged": logged.tick}
    bt = _btcpp()
    logger = None
    if bt is not None:
        theirs, theirs_logged = (bt.BehaviorTreeFactory().create_tree_from_text(XML) for _ in "ab")
        logger = bt.FileLogger(theirs_logged, str(folder / "btcpp.btlog"))
        ticks["btcpp"] = theirs.tick_exactly_once
        ticks["btcpp_logged"] = theirs_logged.tick_exactly_once
    try:
        samples = time_shape(ticks, warmup, count)
    finally:
        recorder.close()
        del logger
    ours = read_btlog(folder / "btcap.btlog")
    assert len(ours.transitions) % per_tick == 0, "every tick logs the same changes"
    for f in folder.iterdir():
        f.unlink()
    folder.rmdir()

    def median(lib: str, kind: str) -> float:
        return percentiles(samples[lib][kind])["p50"]

    data: dict[str, Any] = {"fallbacks": FALLBACKS, "changes_per_tick": per_tick}
    for kind in ("wall", "cpu"):
        for lib in ("btcap", "btcpp"):
            if lib in ticks:
                extra = (median(f"{lib}_logged", kind) - median(lib, kind)) / per_tick
                data[f"{lib}_ns_per_change_{kind}"] = round(extra, 1)
                data[f"{lib}_tick_us_{kind}"] = round(median(lib, kind) / 1000, 2)
        if "btcpp" in ticks:
            ratio = data[f"btcap_ns_per_change_{kind}"] / max(
                data[f"btcpp_ns_per_change_{kind}"], 1
            )
            data[f"btcap_over_btcpp_{kind}"] = round(ratio, 2)
    data["load_average"] = [load_start, load_average()]
    print(f".btlog cost per status change ({per_tick} changes a tick), median:")
    for key, value in data.items():
        if "per_change" in key or "over" in key or "tick_us" in key:
            print(f"  {key:32s} {value}")
    write_result("btlog", data)
    return data


if __name__ == "__main__":
    import sys

    run(quick="--quick" in sys.argv)
