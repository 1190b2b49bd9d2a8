"""A sixth allocation strategy, written outside the package with public names only."""

from __future__ import annotations

import random
from collections.abc import Sequence, Set
from pathlib import Path

import anyio
import pytest
from capfixtures import COUNT, Probe, count_impl, team, tick_until

from btcap import BatchStrategy, Parallel, State
from btcap.team.allocation.strategies import check_strategy, get, names
from btcap.team.messages import Bid


class RandomPolicy:
    """Each auction of a batch goes to a random free bidder."""

    batches = True

    def __init__(self, seed: int) -> None:
        self.rng = random.Random(seed)
        self.planned = 0

    def plan(self, bids: Sequence[Sequence[Bid]], taken: Set[str]) -> list[str | None]:
        self.planned += len(bids)
        used, out = set(taken), []
        for task in bids:
            free = sorted({b.robot for b in task} - used)
            pick = self.rng.choice(free) if free else None
            used.add(pick or "")
            out.append(pick)
        return out

    def first(self, ordered: Sequence[Sequence[Bid]]) -> int:
        return 0


POLICY = RandomPolicy(seed=3)
RANDOM = BatchStrategy("random", POLICY)


async def test_a_team_runs_with_a_strategy_from_outside() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team(strategy=RANDOM, reevaluate_s=None) as t:
            a = await t.add("a")
            for r in "bcd":
                await t.add(r, [count_impl(r, 1.0, probe)])
            await t.converged()
            nodes = [COUNT.node_type()(f"n{i}", inputs={"x": i, "stop": True}) for i in range(3)]
            tree = a.mission(Parallel("all", children=nodes))
            assert await tick_until(tree, lambda s: s is not State.RUNNING) is State.SUCCEEDED
            assert sorted(r for n in nodes for r in n.assignments) == ["b", "c", "d"]
            assert POLICY.planned >= 3  # the team's auctioneer asked it
            await tree.shutdown()


def test_a_strategy_is_found_by_its_entry_point(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "random_alloc.py").write_text(
        "from btcap.team.core.turns import ARRIVAL\n"
        "from btcap import BatchStrategy\n"
        "RANDOM = BatchStrategy('random', ARRIVAL)\n"
    )
    info = tmp_path / "random_alloc-0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: random-alloc\nVersion: 0\n")
    (info / "entry_points.txt").write_text("[btcap.strategies]\nrandom = random_alloc:RANDOM\n")
    with pytest.raises(ValueError, match="'random': expected one of auction, seq"):
        check_strategy("random")
    monkeypatch.syspath_prepend(str(tmp_path))
    assert names()[-1] == "random"
    assert check_strategy("random") == "random"
    assert get("random").name == "random"
    with pytest.raises(ValueError, match=r"'nope': expected one of auction.*, random"):
        get("nope")
