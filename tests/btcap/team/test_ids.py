"""Execution and auction ids: minted with the origin's incarnation, so a robot restarted
under the same name never reuses an id its teammates remember from its last life."""

from __future__ import annotations

import anyio
import msgspec
from capfixtures import COUNT, Probe, count_impl, team, tick_until

from btcap import ReactiveSequence
from btcap.bt.state import State
from btcap.team.allocation.strategy import AuctionRecord
from btcap.team.core.body import Body
from btcap.team.core.hosting import HostLeases
from btcap.team.core.task import Assigned
from btcap.team.ids import AuctionId, ExecutionId, incarnation_tag
from btcap.team.messages import Award, RunState
from btcap.team.runtime.agent import Agent


def test_ids_read_as_origin_tag_path_number_and_tell_lives_apart() -> None:
    old = ExecutionId("operator", "greetings/ada", 1, 0x1234_3F2A)
    new = ExecutionId("operator", "greetings/ada", 1, 0x1234_3F2B)
    assert str(old) == "operator~3f2a:greetings/ada#1"
    assert str(AuctionId("operator", 7, 0x3F2A)) == "operator~3f2a#7"
    assert old != new
    assert len({old, new}) == 2
    # Ids made by hand (no incarnation) read as before.
    assert str(ExecutionId("x", "root", 1)) == "x:root#1"
    assert str(AuctionId("x", 1)) == "x#1"
    assert incarnation_tag(0) == ""
    assert incarnation_tag(0xABCDEF) == "~cdef"


def test_the_incarnation_survives_the_wire_and_an_id_without_one_still_decodes() -> None:
    ex = ExecutionId("a", "root/count", 3, 2**63 - 1)
    assert msgspec.msgpack.decode(msgspec.msgpack.encode(ex), type=ExecutionId) == ex
    auction = AuctionId("a", 3, 2**63 - 1)
    assert msgspec.msgpack.decode(msgspec.msgpack.encode(auction), type=AuctionId) == auction
    legacy = msgspec.msgpack.encode(["a", "root/count", 3])
    assert msgspec.msgpack.decode(legacy, type=ExecutionId) == ExecutionId("a", "root/count", 3)


def test_a_restarted_origins_award_is_not_taken_for_one_it_made_before() -> None:
    leases: HostLeases[object] = HostLeases("b", Body())
    first = ExecutionId("a", "root/count", 1, 100)
    award = Award(AuctionId("a", 1, 100), first, "Count", "count-b", {"x": 1}, 1.0)
    assert leases.refuse_award("a", award) is None
    leases.admit(award, object(), {"x": 1}, 1.0, now=0.0)
    leases.ticked(first, RunState.SUCCEEDED, {})
    assert leases.refuse_award("a", award) == f"{first} was awarded before"
    again = ExecutionId("a", "root/count", 1, 200)  # a's next life: numbers start over
    award2 = Award(AuctionId("a", 1, 200), again, "Count", "count-b", {"x": 1}, 1.0)
    assert leases.refuse_award("a", award2) is None


def test_an_agent_mints_ids_of_its_own_life() -> None:
    one, two = Agent("a"), Agent("a")
    assert one.team.incarnation != two.team.incarnation
    node = COUNT.node_type()("count", inputs={"x": 1})
    first = one.mission_control.origin_side.new_execution(node)
    second = two.mission_control.origin_side.new_execution(node)
    assert (first.origin, first.node, first.number) == (second.origin, second.node, 1)
    assert first.incarnation == one.team.incarnation
    assert first != second


async def test_the_same_mission_from_a_restarted_origin_is_won_by_its_first_auction() -> None:
    """b remembers a's finished runs; a's next life runs the same tree and b takes it."""
    with anyio.fail_after(20):
        probe = Probe()
        async with team() as t:
            await t.add("b", [count_impl("b", 1.0, probe, after=2)])
            for life in range(2):
                a = await t.add("a")
                await t.converged()
                records: list[AuctionRecord] = []
                a.allocator.watch(records.append)
                node = COUNT.node_type()("count", inputs={"x": 1})
                tree = a.mission(ReactiveSequence("root", children=[node]))
                await tick_until(tree, lambda s: s is State.SUCCEEDED, f"life {life} succeeds")
                (rec,) = [r for r in records if r.closed is not None]
                assert isinstance(rec.result, Assigned), rec
                assert rec.result.robot == "b", rec
                assert rec.passed == {}, rec
                assert rec.id.incarnation == rec.task.execution.incarnation == a.team.incarnation
                assert str(rec.id).startswith(f"a{incarnation_tag(a.team.incarnation)}#")
                await tree.shutdown()
                await t.remove("a")
