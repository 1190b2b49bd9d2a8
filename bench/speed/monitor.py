"""What a live monitor costs the ticking robot: the tick benchmark's btcap shapes with a
:class:`~btcap.Monitor` attached and one page connected, against the same trees without.

Shapes as in :mod:`.tick` (``flat``, ``balanced``: a tick changes no state once they
settled; ``mixed``, ``mixed_parallel``: seeded random trees ticked from reset, many state
changes per tick). Each shape is built twice; one copy is shown by a monitor serving on
loopback, with a WebSocket client in another process reading every batch. The two take
turns in blocks of ``BLOCK_S``; every block of the monitored copy ends with the monitor's
flush and the send to the page, so batches go out at about 20 a second as they do live
(every other one after a reset, so that in mixed shapes most nodes differ from the last
batch: the worst case).

Reported per shape, in microseconds per tick (``mixed``: per run of 16 steps): the
median tick without and with the monitor, by thread CPU time (``cpu_ratio`` = on / off,
steady on a shared machine) and by wall time (``ratio``); and the thread CPU time of one
batch (``flush_cpu_us``: reading the trees' states, encoding, queueing and sending to the
page), which the robot pays at most 20 times a second whatever its tick rate.

Run ``python -m btcap.bench monitor [--quick]``.
"""

from __future__ import annotations

import argparse
import asyncio
import gc
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import btcap
from btcap.bench.common import percentiles, write_result
from btcap.bench.speed.mixed_trees import btcap_run, mixed_spec
from btcap.bench.speed.shapes import balanced_spec, build_btcap, flat_spec
from btcap.bench.speed.tick import MIXED_SEED, MIXED_TREES

__all__ = ["run"]

SHAPES = ("flat", "balanced", "mixed", "mixed_parallel")
BLOCK_S = 0.025
CONDITIONS = ("off", "on")

#: The page: connects, says so, then reads every message until the server goes away.
CLIENT = """
import asyncio, sys, aiohttp
async def main():
    async with aiohttp.ClientSession() as s, s.ws_connect(sys.argv[1]) as ws:
        print("connected", flush=True)
        async for _ in ws:
            pass
asyncio.run(main())
"""


@dataclass
class _Shape:
    """One copy of a shape: what one timed sample does, and the trees it ticks."""

    sample: Callable[[], object]
    trees: list[btcap.Tree]
    reset: Callable[[], None] = lambda: None


@dataclass
class _Samples:
    wall: list[float] = field(default_factory=list)
    cpu: list[float] = field(default_factory=list)
    flush_cpu: list[float] = field(default_factory=list)
    blocks: int = 0


def _build(shape: str) -> _Shape:
    if shape in ("flat", "balanced"):
        spec = flat_spec(1000) if shape == "flat" else balanced_spec()
        tree = btcap.Tree(build_btcap(spec))
        tree.setup()
        return _Shape(tree.tick, [tree])
    parallel = shape == "mixed_parallel"
    specs = [mixed_spec(MIXED_SEED + i, parallel=parallel) for i in range(MIXED_TREES)]
    r = btcap_run(specs)
    trees = [tick.__self__ for tick in r.ticks]  # type: ignore[attr-defined]
    return _Shape(r.run, trees, r.reset)


async def _block(s: _Shape, n: int, out: _Samples, flush: Callable[[], object] | None) -> None:
    wall_clock, cpu_clock = time.perf_counter_ns, time.thread_time_ns
    for _ in range(n):
        s.reset()
        c0 = cpu_clock()
        t0 = wall_clock()
        s.sample()
        t1 = wall_clock()
        c1 = cpu_clock()
        out.wall.append(t1 - t0)
        out.cpu.append(c1 - c0)
    c0 = cpu_clock()
    if flush is not None:
        out.blocks += 1
        if out.blocks % 2:  # every other batch from reset: each differs from the last
            s.reset()
        c0 = cpu_clock()
        flush()
    await asyncio.sleep(0)  # the page's sender runs
    if flush is not None:
        out.flush_cpu.append(cpu_clock() - c0)


async def _time(shapes: dict[str, _Shape], flush: Callable[[], object], warmup: int, count: int
                ) -> dict[str, _Samples]:  # fmt: skip
    per_block: dict[str, int] = {}
    for cond, s in shapes.items():
        t0 = time.perf_counter()
        for _ in range(warmup):
            s.reset()
            s.sample()
        per_block[cond] = max(1, round(BLOCK_S * warmup / (time.perf_counter() - t0)))
    flush()
    samples = {cond: _Samples() for cond in shapes}
    gc.collect()
    while any(len(samples[c].wall) < count for c in shapes):
        for cond, s in shapes.items():
            await _block(s, per_block[cond], samples[cond], flush if cond == "on" else None)
    return samples


async def _measure(quick: bool) -> dict[str, Any]:
    warmup, count = (20, 200) if quick else (100, 1000)
    data: dict[str, Any] = {
        k: {} for k in ("us_per_tick", "cpu_us_per_tick", "ratio", "cpu_ratio", "flush_cpu_us")
    }
    data["batches"] = {}
    async with btcap.Monitor(port=0, title="bench") as monitor:
        url = monitor.url.replace("http://", "ws://") + "ws"
        page = await asyncio.create_subprocess_exec(
            sys.executable, "-c", CLIENT, url, stdout=asyncio.subprocess.PIPE
        )
        try:
            assert page.stdout is not None
            await asyncio.wait_for(page.stdout.readline(), 60)
            for shape in SHAPES:
                copies = {"off": _build(shape), "on": _build(shape)}
                detach = [monitor.add_tree(t, robot="bench") for t in copies["on"].trees]
                sent = monitor.hub.sent
                mixed = shape.startswith("mixed")
                n = (max(2, warmup // 10), max(20, count // 10)) if mixed else (warmup, count)
                samples = await _time(copies, monitor.flush, *n)
                for d in detach:
                    d()
                p50 = {
                    kind: {
                        c: percentiles([v / 1000 for v in getattr(samples[c], kind)])["p50"]
                        for c in copies
                    }
                    for kind in ("wall", "cpu")
                }
                data["us_per_tick"][shape] = p50["wall"]
                data["cpu_us_per_tick"][shape] = p50["cpu"]
                data["ratio"][shape] = p50["wall"]["on"] / p50["wall"]["off"]
                data["cpu_ratio"][shape] = p50["cpu"]["on"] / p50["cpu"]["off"]
                flushes = [v / 1000 for v in samples["on"].flush_cpu]
                data["flush_cpu_us"][shape] = percentiles(flushes)["p50"]
                data["batches"][shape] = monitor.hub.sent - sent
            assert monitor.hub.clients == 1, "the page went away during the benchmark"
        finally:
            page.terminate()
            await page.wait()
    data["quick"] = quick
    data["block_s"] = BLOCK_S
    return data


def _table(data: dict[str, Any]) -> str:
    lines = [
        f"{'us per tick':<15} {'cpu off':>8} {'cpu on':>8} {'on/off':>7} {'wall on/off':>11} "
        f"{'us/batch':>9} {'batches':>8}",
        "-" * 72,
    ]
    for shape in SHAPES:
        cpu = data["cpu_us_per_tick"][shape]
        lines.append(
            f"{shape:<15} {cpu['off']:>8.1f} {cpu['on']:>8.1f} {data['cpu_ratio'][shape]:>6.3f}x "
            f"{data['ratio'][shape]:>10.3f}x {data['flush_cpu_us'][shape]:>9.0f} "
            f"{data['batches'][shape]:>8}"
        )
    lines.append(
        "on: a Monitor shows the trees, one page (another process) reads every batch; "
        "us/batch: CPU of one flush and send (at most 20 a second)"
    )
    return "\n".join(lines)


def run(quick: bool = False) -> dict[str, Any]:
    """Measure, print a table, write ``bench/results/monitor.json``."""
    data = asyncio.run(_measure(quick))
    print(_table(data))
    print(f"wrote {write_result('monitor', data)}")
    return data


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m btcap.bench.speed.monitor", description=__doc__
    )
    parser.add_argument("--quick", action="store_true", help="fewer ticks, for CI smoke runs")
    run(quick=parser.parse_args(argv).quick)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
