"""The auction bench's table says plainly whether DESIGN's budget was met and whether the
hand-written floor itself is above it on this machine."""

from __future__ import annotations

from typing import Any

import pytest

from btcap.bench.speed.auction_report import table, to_floor

ROWS = ("1", "3", "10", "10_of_51", "50")


def _results(tcp_ms: float, floor_ms: float) -> dict[str, Any]:
    row = {"p50": tcp_ms, "p90": tcp_ms, "p99": tcp_ms}
    cpu = {"this_process": 1.0, "bidder_processes": 2.0}
    rounds = {k: dict(row) for k in (*ROWS, "isolated")}
    floor = {
        v: {k: {"p50": floor_ms, "p90": floor_ms, "p99": floor_ms} for k in (*ROWS[:3], "50")}
        for v in ("blocking", "asyncio")
    }
    tcp = {"zmq_tcp": rounds, "zmq_tcp_curve": rounds}
    floors = {"zmq_tcp": floor, "zmq_tcp_curve": floor}
    return {
        "round_ms": {"inproc": rounds, **tcp},
        "round_cpu_ms": {s: {k: dict(cpu) for k in ROWS} for s in ("inproc", *tcp)},
        "floor_ms": floors,
        "round_to_floor": to_floor(tcp, floors, "10_of_51", "10"),
        "ask_us": {"zmq_tcp_ask": {"p50": 150.0}, "raw_zmq_tcp_blocking": {"p50": 70.0}},
        "round_to_ask": {
            "bidders": 10,
            "round_p50_over_tcp_ask_p50": 10.0,
            "round_p50_over_floor_p50": 20.0,
        },
        "early_close": {"all": True},
        "remote_tick_ms": {"p50": 0.1, "p99": 0.2},
        "failover_s": {"p50": 0.7, "max": 0.8, "repeats": 2},
        "setup": {
            "bidders": [1, 3, 10, 50],
            "teams": {"1": 2, "3": 4, "10": 11, "10_of_51": 51, "50": 51},
            "crowded_row": "10_of_51",
            "burst_rounds": 100,
            "isolated_gap_s": 0.05,
            "bidder_processes": 4,
            "load_average": [1.0, 1.0],
        },
    }


@pytest.mark.parametrize(
    ("tcp_ms", "floor_ms", "says"),
    [
        (0.9, 0.5, "budget, 10 bidders over tcp p50 <= 1 ms: met (0.900 ms, 1.80x"),
        (1.5, 0.6, "budget, 10 bidders over tcp p50 <= 1 ms: NOT met (1.500 ms, 2.50x"),
        (2.4, 1.2, "the floor itself is ABOVE 1 ms on this machine now (1.200 ms)"),
    ],
)
def test_the_table_says_whether_the_budget_and_the_floor_are_met(
    tcp_ms: float, floor_ms: float, says: str
) -> None:
    text = table(_results(tcp_ms, floor_ms), 5.0)
    assert says in text
    assert ("ABOVE 1 ms" in text) == (floor_ms > 1.0)
    # the crowded row has its own line, against the floor's row of 10
    crowded = next(line for line in text.splitlines() if line.lstrip().startswith("10/51"))
    assert f"{tcp_ms / floor_ms:.2f}" in crowded


def test_the_crowded_row_is_given_against_the_floors_row_of_ten() -> None:
    rounds = {"zmq_tcp": {"10": {"p50": 2.0}, "10_of_51": {"p50": 3.0}, "isolated": {}}}
    floor = {"zmq_tcp": {"asyncio": {"10": {"p50": 1.0}}}}
    assert to_floor(rounds, floor, "10_of_51", "10") == {
        "zmq_tcp": {"asyncio": {"10": 2.0, "10_of_51": 3.0}}
    }
