"""Mission control against its own awkward cases and against peers that lie: each test
was a bug once (a withdrawn self-award holding the body, an unencodable output stopping
mission control, strangers editing a robot's executions)."""

from __future__ import annotations

from typing import Any

import anyio
from capfixtures import COUNT, Probe, count_impl, team, tick_until, until

from btcap import Leaf, ReactiveSequence, State, Tree
from btcap.team.capabilities.capability import CapabilityInterface
from btcap.team.capabilities.implementation import Implementation
from btcap.team.capabilities.proxies import LocalExecution
from btcap.team.ids import AuctionId, ExecutionId
from btcap.team.messages import Award, AwardReply, CancelExecution, ExecutionStatus, RunState
from btcap.transports import Address

MC = "mission_control"


async def test_a_withdrawn_award_to_itself_frees_the_body() -> None:
    """The auctioneer's ask to its own mission control timed out (it waited in a busy
    mailbox), so it withdrew the award: the run it took for itself must not keep the body."""
    with anyio.fail_after(10):
        probe = Probe()
        async with team() as t:
            a = await t.add("a", [count_impl("a", 1.0, probe)])
            mc = a.mission_control
            execution = ExecutionId("a", "root/count", 99)
            award = Award(AuctionId("a", 99), execution, "Count", "count-a", {"x": 1}, 1.0)
            mc.executor.bids.bid(award.auction, "Count", a.clock.now())  # it bid in its auction
            reply = await a.system.ref(Address("a", MC)).ask(award, expect=AwardReply)
            assert reply.accepted
            assert mc.body.running == execution
            a.system.tell(Address("a", MC), CancelExecution(execution, "award withdrawn"))
            assert mc.body.idle
            assert execution not in mc.executor.local_runs
            await until(lambda: probe.live("a") == 0, "the run to be closed")


async def test_nobody_else_ends_a_robots_own_execution() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team() as t:
            a = await t.add("a", [count_impl("a", 1.0, probe)])
            x = await t.add("x")
            await t.converged()
            node = COUNT.node_type()("count", inputs={"x": 1})
            tree = a.mission(ReactiveSequence("root", children=[node]))
            await tick_until(tree, lambda _s: node.state is State.RUNNING, "running")
            ex = node.execution
            assert isinstance(ex, LocalExecution)
            mc = a.mission_control
            forged = ExecutionStatus(ex.id, "a", RunState.SUCCEEDED, {"y": 666})
            x.system.tell(Address("a", MC), forged)
            ticks = node.outputs["ticks"]
            await tick_until(tree, lambda _s: node.outputs["ticks"] > ticks + 3, "more ticks")
            assert ex.id in mc.active
            assert node.state is State.RUNNING
            await tree.shutdown()


BLOB = CapabilityInterface("Blob", outputs={"blob": Any})


class MakeBlob(Leaf):
    OUTPUTS = {"blob": Any}
    OPTIONS = {"finish": bool}

    def on_tick(self) -> State:
        self.outputs["blob"] = object()  # nothing the codec can send
        return State.SUCCEEDED if self.options["finish"] else State.RUNNING


def blob_impl(finish: bool) -> Implementation:
    def build() -> Tree:
        _ib, ob = BLOB.bridge_types()
        make, out = MakeBlob("make", finish=finish), ob(name="out")
        tree = Tree(ReactiveSequence("impl", children=[out, make]))
        tree.wire(make, "blob", out, "blob")
        return tree

    return Implementation("blob-b", BLOB, build, (), lambda _inputs: 1.0)


async def _blob_mission(finish: bool) -> None:
    async with team() as t:
        a = await t.add("a")
        b = await t.add("b", [blob_impl(finish)])
        await t.converged(BLOB.identity)
        node = BLOB.node_type()("blob")
        tree = a.mission(ReactiveSequence("root", children=[node]))
        # The executor cannot send the run's status: it gives the run up as failed,
        # says so in a form it can send, and stays able to work.
        assert await tick_until(tree, lambda s: s is not State.RUNNING) is State.FAILED
        mc = b.mission_control
        assert mc.stats.errors >= 1
        assert not mc.host.hosted
        assert mc.slot is not None
        assert mc.slot.current is None
        assert mc.body.idle
        assert b.system.lookup(MC) is mc
        await tree.shutdown()


async def test_an_unencodable_result_fails_the_run_and_frees_the_executor() -> None:
    with anyio.fail_after(20):
        await _blob_mission(finish=True)


async def test_an_unencodable_running_status_fails_the_run_and_frees_the_executor() -> None:
    with anyio.fail_after(20):
        await _blob_mission(finish=False)
