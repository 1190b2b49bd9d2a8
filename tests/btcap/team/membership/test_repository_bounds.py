"""What teammates' capability lists may cost a robot (issue 19, item 5): one member's,
and the whole team's, are bounded; a member's cost is released when it goes."""

from __future__ import annotations

import anyio
from capfixtures import Probe, count_impl, step, team, until

from btcap.team.membership.repository import MAX_STATE_COST, state_cost
from btcap.team.messages import RepositoryQuery, RepositoryState
from btcap.transports import Address

REPO = "repository"


def big(robot: str, version: int, entries: int, width: int = 1000) -> RepositoryState:
    return RepositoryState(robot, version, {f"Iface{k}": "i" * width for k in range(entries)})


def test_the_cost_of_a_state_grows_with_what_it_holds() -> None:
    small = RepositoryState("x", 1, {"Count": "Count(x:int)->()"})
    assert state_cost(small) < 512
    assert state_cost(big("x", 1, 1000)) > 1_000_000 > MAX_STATE_COST


async def test_a_members_oversized_capability_list_is_not_held() -> None:
    with anyio.fail_after(10):
        async with team() as t:
            a = await t.add("a")
            x = await t.add("x")
            await t.converged()
            repo = a.repository
            x.system.tell(Address("a", REPO), big("x", 99, 1000))  # 1 MB of interfaces
            await until(lambda: repo.oversized == 1, "the state refused")
            assert repo.team["x"].version < 99
            x.system.tell(Address("a", REPO), big("x", 100, 10))
            await until(lambda: repo.team["x"].version == 100, "a small one held")


async def test_the_whole_teams_capability_lists_are_bounded_and_released() -> None:
    with anyio.fail_after(10):
        async with team() as t:
            a = await t.add("a")
            others = [await t.add(f"m{n}") for n in range(4)]
            await t.converged()
            repo = a.repository
            repo.max_team_cost = 3 * state_cost(big("m0", 1, 50)) + 2000
            for n, m in enumerate(others):
                m.system.tell(Address("a", REPO), big(m.robot, 50 + n, 50))
            await until(lambda: repo.oversized >= 1, "the team's bound reached")
            held = [r for r, st in repo.team.items() if st.version >= 50]
            assert len(held) == 3
            # A member that goes releases what its list cost: the next one fits.
            gone = held[0]
            await t.remove(gone)
            await until(lambda: gone not in repo.team, f"{gone} gone")
            late = next(m for m in others if m.robot not in held)
            late.system.tell(Address("a", REPO), big(late.robot, 90, 50))
            await until(lambda: repo.team[late.robot].version == 90, "the late one held")


async def test_repository_queries_beyond_a_members_budget_are_not_answered() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team() as t:
            a = await t.add("a", [count_impl("a", 1.0, probe)])
            x = await t.add("x")
            await t.converged()
            for _ in range(200):
                x.system.tell(Address("a", REPO), RepositoryQuery("x"))
            await step()
            assert 150 <= a.repository.queries.refused <= 190
