"""The monitor's picture (TeamView) on explicit events: identical auctions of one node
folded into one row, and how a run ended."""

from __future__ import annotations

from typing import Any

from btcap.monitor import TeamView
from btcap.monitor.view import MAX_AUCTIONS

NODE_A = "operator:mission/loop_1/decontaminate"
NODE_B = "operator:mission/loop_2/decontaminate"
BUSY = {"husky1": "busy", "spot1": "cannot"}


def _auction(
    view: TeamView,
    n: int,
    t: float,
    node: str = NODE_A,
    *,
    why: str = "retry: nobody took it last time",
    bids: list[list[Any]] | None = None,
    declined: dict[str, str] | None = None,
    winner: str | None = None,
    reasons: dict[str, str] | None = None,
    close: bool = True,
) -> None:
    """Auction ``operator#n`` for ``node`` opened at ``t`` and closed at ``t + 0.5``."""
    base = {"k": "auction", "id": f"operator#{n}", "execution": f"{node}#1"}
    view.apply({**base, "t": t, "phase": "open", "auctioneer": "operator",
                "capability": "MoveToDecontamination", "node": node,
                "candidates": ["husky1"], "why": why})  # fmt: skip
    if close:
        declined = BUSY if declined is None else declined
        view.apply({**base, "t": t + 0.5, "phase": "close", "bids": bids or [],
                    "declined": declined, "reasons": reasons or dict(declined),
                    "winner": winner})  # fmt: skip


def _rows(view: TeamView) -> list[tuple[str, int, float, float]]:
    """(id, count, first, opened) of each row, oldest first."""
    return [(a["id"], a["count"], a["first"], a["opened"]) for a in view.snapshot()["auctions"]]


def test_identical_retries_of_a_node_are_one_row_with_a_count_and_a_time_span() -> None:
    view = TeamView()
    _auction(view, 1, 10.0, why="first request")
    for n in range(2, 7):
        _auction(view, n, 10.0 * n)
    assert _rows(view) == [("operator#1", 1, 10.0, 10.0), ("operator#6", 5, 20.0, 60.0)]
    row = view.snapshot()["auctions"][-1]
    assert row["closed"] == 60.5
    assert row["why"] == "retry: nobody took it last time"
    assert row["declined"] == BUSY


def test_rows_of_other_nodes_in_between_do_not_stop_the_folding() -> None:
    """Two tasks retried by turns: a row each, each where its latest auction is."""
    view = TeamView()
    for n in range(1, 9):
        _auction(view, n, float(n), NODE_A if n % 2 else NODE_B)
    assert _rows(view) == [("operator#7", 4, 1.0, 7.0), ("operator#8", 4, 2.0, 8.0)]


def test_an_auction_that_ended_otherwise_starts_a_row_of_its_own() -> None:
    view = TeamView()
    _auction(view, 1, 1.0)
    _auction(view, 2, 2.0)
    _auction(view, 3, 3.0, bids=[["husky1", 376.0]], declined={}, winner="husky1")  # taken
    _auction(view, 4, 4.0, why="new run (the last one succeeded)")  # another reason
    _auction(view, 5, 5.0, declined={"husky1": "busy"})  # other declines
    _auction(view, 6, 6.0, declined={"husky1": "busy"})
    _auction(view, 7, 7.0, bids=[["husky1", 376.0]], declined={})  # a bid, kept out
    _auction(view, 8, 8.0, bids=[["husky1", 376.0], ["spot1", 400.0]], declined={})  # 2 bids
    _auction(view, 9, 9.0, bids=[["husky1", 376.0]], declined={}, winner="husky1")
    _auction(view, 10, 10.0, bids=[["husky1", 377.0]], declined={}, winner="husky1")  # cost
    counts = [(i, c) for i, c, _, _ in _rows(view)]
    assert counts == [
        ("operator#2", 2),
        ("operator#3", 1),
        ("operator#4", 1),
        ("operator#6", 2),
        ("operator#7", 1),
        ("operator#8", 1),
        ("operator#9", 1),
        ("operator#10", 1),
    ]


def test_retries_nobody_took_fold_whatever_the_busy_robot_asked() -> None:
    """A busy robot's cost falls as it drives to its current work (what full-team shows:
    forty retries of one decontamination, each a row of its own before): one row, the
    latest bids, while the same robots bid and nobody takes it."""
    view = TeamView()
    why = "retry: nobody took it last time"
    for n in range(1, 41):
        cost = 600.0 - 5 * n
        busy = {"husky1": f"busy (would cost {cost:g} after its current work)"}
        base = {"k": "auction", "id": f"operator#{n}", "execution": f"{NODE_A}#1"}
        view.apply({**base, "t": 10.5 * n, "phase": "open", "auctioneer": "operator",
                    "capability": "MoveToDecontamination", "node": NODE_A,
                    "candidates": ["husky1"], "why": why})  # fmt: skip
        view.apply({**base, "t": 10.5 * n + 0.5, "phase": "close", "bids": [["husky1", cost]],
                    "declined": {}, "reasons": busy, "winner": None})  # fmt: skip
    assert _rows(view) == [("operator#40", 40, 10.5, 420.0)]
    assert view.snapshot()["auctions"][0]["bids"] == [["husky1", 400.0]]


def test_re_evaluations_that_kept_the_holder_fold_per_node_and_holder() -> None:
    """Every 30 s each running task is re-auctioned and stays (huskies-bebop-joins: 121 of
    its 189 auctions): a row per task and holder, not a row per look."""
    view = TeamView()
    n = 0
    for k in range(10):
        for node, holder, other in ((NODE_A, "husky1", "husky2"), (NODE_B, "husky2", "husky1")):
            n += 1
            cost = 300.0 - 30 * k
            reasons = {other: "busy", holder: f"bid {cost:g} not below {0.8 * cost:g}"}
            _auction(view, n, 30.0 * k, node, why=f"re-evaluation: may move from {holder}",
                     bids=[[holder, cost]], declined={other: "busy"}, reasons=reasons)  # fmt: skip
    assert [(i, c) for i, c, _, _ in _rows(view)] == [("operator#19", 10), ("operator#20", 10)]


def test_declines_in_another_order_are_the_same_and_an_open_auction_is_not_folded() -> None:
    view = TeamView()
    _auction(view, 1, 1.0, declined={"a": "busy", "b": "busy"})
    _auction(view, 2, 2.0, declined={"b": "busy", "a": "busy"})
    _auction(view, 3, 3.0, close=False)
    assert [(i, c) for i, c, _, _ in _rows(view)] == [("operator#2", 2), ("operator#3", 1)]
    assert view.snapshot()["auctions"][-1]["closed"] is None
    # the next one for the node follows an open auction (not folded: it closed unlike it)
    _auction(view, 4, 4.0, declined={"a": "busy", "b": "busy"})
    assert [c for _, c, _, _ in _rows(view)] == [2, 1, 1]


def test_a_task_retried_for_hours_is_one_row_and_older_rows_stay() -> None:
    view = TeamView()
    _auction(view, 0, 0.0, NODE_B, why="first request")
    for n in range(1, 10 * MAX_AUCTIONS):
        _auction(view, n, float(n))
    assert _rows(view) == [
        ("operator#0", 1, 0.0, 0.0),
        (f"operator#{10 * MAX_AUCTIONS - 1}", 10 * MAX_AUCTIONS - 1, 1.0, 10.0 * MAX_AUCTIONS - 1),
    ]


def test_how_the_run_ended_is_part_of_the_picture() -> None:
    view = TeamView()
    assert view.snapshot()["finished"] is None
    view.apply({"t": 3.0, "k": "robot", "robot": "a"})
    end = {"t": 1337.0, "k": "finished", "result": "succeeded",
           "summary": "mission succeeded after 1337 s"}  # fmt: skip
    view.apply(end)
    assert view.snapshot()["finished"] == {k: end[k] for k in ("t", "result", "summary")}
    assert view.t == 1337.0
