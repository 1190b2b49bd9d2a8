"""The per-robot agent: wiring, missions, leaving cleanly; and the capability protocol
on the wire."""

from __future__ import annotations

import asyncio
import math
from typing import Any

import anyio
import pytest
from capfixtures import COUNT, Probe, count_impl, team, tick_until, until

from btcap import ReactiveSequence, State
from btcap.team.allocation.auction import SingleItemAuction
from btcap.team.ids import AuctionId, ExecutionId
from btcap.team.membership.membership import Membership, TeamEvent
from btcap.team.membership.repository import CapabilityRepository
from btcap.team.messages import (
    CAPABILITY_MESSAGES,
    Activity,
    ActivityQuery,
    Award,
    AwardReply,
    Bid,
    CallForBids,
    CancelExecution,
    ConsensusClaim,
    ConsensusPrices,
    ConsensusTasks,
    Contact,
    CostChanged,
    Departed,
    Departures,
    DeparturesQuery,
    ExecutionInputs,
    ExecutionStatus,
    Goodbye,
    Heard,
    Heartbeat,
    KeepAlive,
    NoBid,
    OpenTask,
    PauseExecution,
    ProbeRequest,
    RepositoryQuery,
    RepositoryState,
    Roster,
    RosterRequest,
    RunState,
    Seen,
    StatusQuery,
    TeamStatus,
    Vouch,
)
from btcap.team.runtime.agent import Agent, AgentConfig
from btcap.team.runtime.mission import MissionConfig, MissionControl
from btcap.team.runtime.protocol import protocol_registry
from btcap.transports import Address, Codec, Envelope, Kind, Message

# -- protocol -----------------------------------------------------------------------------

A1 = AuctionId("a", 1)
E1 = ExecutionId("a", "root/count", 1)
E2 = ExecutionId("a", "root/other", 2)

SAMPLES: dict[type[Message], list[Message]] = {
    Heartbeat: [
        Heartbeat("husky1", 2**62, 7),
        Heartbeat("b", 1, 0, True, 12, [Heard("a", 2**62, 3), Heard("c", 1, 0)]),
        Heartbeat("b", 1, 0, False, 3, [Heard("c", 1, 4, 0, True, "a")], probe=9, ack=2**40),
    ],
    ProbeRequest: [ProbeRequest("c", 2**40)],
    Vouch: [Vouch("c", 7, 2**62, 3)],
    Goodbye: [Goodbye("husky1", 123)],
    Roster: [Roster([Contact("a", "tcp://127.0.0.1:7001")]), Roster([])],
    RosterRequest: [RosterRequest(["a", "c"]), RosterRequest([])],
    ActivityQuery: [ActivityQuery()],
    Activity: [Activity("b", [E1], [E2]), Activity("b", [])],
    StatusQuery: [StatusQuery()],
    TeamStatus: [
        TeamStatus("b", {"Greet": "Greet:1"}, ["Greet"], [E1], [E2], [Seen("a", "tcp://h:1", 7)]),
        TeamStatus("b", {}, [], [], [], []),
    ],
    RepositoryState: [
        RepositoryState("a", 3, {"Count": COUNT.identity}, ["Count", "Explore"]),
        RepositoryState("a", 0, {}),
    ],
    RepositoryQuery: [RepositoryQuery("spot")],
    CallForBids: [
        CallForBids(A1, "Count", COUNT.identity, {"x": 3, "goal": [1.5, 2.0], "n": None})
    ],
    Bid: [Bid(A1, "b", 2.5, "count-b"), Bid(A1, "b", 0.0, "i")],
    NoBid: [NoBid(A1, "c", "busy"), NoBid(A1, "c", "")],
    Award: [
        Award(A1, E1, "Count", "count-b", {"x": 3}, 1.0),
        Award(A1, E1, "Count", "count-b", {}, 0.5, paused=True),
    ],
    AwardReply: [AwardReply(E1, "b", True), AwardReply(E2, "b", False, "busy")],
    ExecutionInputs: [ExecutionInputs(E1, 42, {"x": -3, "stop": True})],
    ExecutionStatus: [
        ExecutionStatus(E1, "b", state, {"y": 1, "robot": "b"}, 9, "detail") for state in RunState
    ],
    PauseExecution: [PauseExecution(E1)],
    CancelExecution: [CancelExecution(E1), CancelExecution(E2, "reset")],
    KeepAlive: [KeepAlive("b", [E1, E2]), KeepAlive("b", [])],
    CostChanged: [CostChanged(E1, 12.5), CostChanged(E2, 0.0)],
    DeparturesQuery: [DeparturesQuery()],
    Departures: [
        Departures("a", [Departed("b", 2**62, "failed", 1200, "no heartbeat for 1 s")]),
        Departures("a", [Departed("c", 7, "left", 0)]),
        Departures("a", []),
    ],
    ConsensusTasks: [
        ConsensusTasks("a", 3, [OpenTask(E1, "Count", COUNT.identity, {"x": 3}, ["b", "c"])]),
        ConsensusTasks("a", 4, [OpenTask(E2, "Count", "", {}, [], E1, "b", 0.2)]),
        ConsensusTasks("a", 5, []),
    ],
    ConsensusClaim: [
        ConsensusClaim("b", 7, 2, E1, 2.5, "count-b", [("a", 1, 3), ("b", 2, 0)]),
        ConsensusClaim("b", 8, 3, None, 0.0, "", [], [(E2, "busy")]),
        ConsensusClaim("b", 9, 4, E1, 2.5, "count-b", [], [], 7.25, 30.0, 3),
    ],
    ConsensusPrices: [
        ConsensusPrices("a", 3, 9, 4, [(E1, 7.25, "b"), (E2, 0.0, None)], 30.5),
        ConsensusPrices("a", 4, 10, 0, [], 0.0),
    ],
}


def test_every_capability_message_has_a_sample() -> None:
    assert set(SAMPLES) == set(CAPABILITY_MESSAGES)
    registry = protocol_registry()
    assert all(t in registry for t in CAPABILITY_MESSAGES)


@pytest.mark.parametrize(
    "msg", [m for ms in SAMPLES.values() for m in ms], ids=lambda m: type(m).__name__
)
def test_capability_messages_round_trip_through_the_codec(msg: Message) -> None:
    codec = Codec(protocol_registry())
    env = Envelope(Kind.TELL, Address("a", "x"), Address("b", "y"), msg, 0)
    back = codec.decode(codec.encode(env))
    assert type(back.msg) is type(msg)
    assert back.msg == msg
    assert codec.decode_message(codec.encode_message(msg)) == msg


def test_run_states_travel_as_the_node_states_values() -> None:
    """The team's run states are their own type, but their wire values are the node
    states' (an executor reports its implementation's root state): LOST is "shutdown".
    A root that skipped itself (BehaviorTree.CPP's SKIPPED) is reported as succeeded."""
    assert [r.value for r in RunState] == [s.value for s in State if s is not State.SKIPPED]
    assert RunState.LOST.value == State.SHUTDOWN.value == "shutdown"
    codec = Codec(protocol_registry())
    wire = codec.encode_message(ExecutionStatus(E1, "b", RunState.LOST, {}))
    assert b"shutdown" in wire
    back = codec.decode_message(wire)
    assert isinstance(back, ExecutionStatus)
    assert back.state is RunState.LOST


def test_nan_cost_survives_the_codec_as_nan() -> None:
    codec = Codec(protocol_registry())
    back = codec.decode_message(codec.encode_message(Bid(A1, "b", math.nan, "i")))
    assert isinstance(back, Bid)
    assert math.isnan(back.cost)


# -- agents -------------------------------------------------------------------------------


def test_agent_config_carries_mission_and_robot_timing() -> None:
    cfg = AgentConfig(tick_hz=5.0, heartbeat_s=0.2, failure_timeout_s=2.0, lease_s=3.0)
    assert isinstance(cfg, MissionConfig)
    assert (cfg.tick_hz, cfg.heartbeat_s, cfg.failure_timeout_s) == (5.0, 0.2, 2.0)
    assert cfg.lease_s == 3.0
    assert cfg.keepalive_s == MissionConfig().keepalive_s
    with pytest.raises(TypeError):
        AgentConfig(tick_rate=5.0)


def test_agent_configs_compare_by_every_field() -> None:
    assert AgentConfig(tick_hz=5) != AgentConfig(tick_hz=50)
    assert AgentConfig(heartbeat_s=0.2, lease_s=2.0) == AgentConfig(heartbeat_s=0.2, lease_s=2.0)
    assert AgentConfig(lease_s=2.0) != AgentConfig(lease_s=3.0)


async def test_agent_wires_one_robot() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team() as t:
            a = await t.add("a", [count_impl("a", 1.0, probe)])
            s = a.system
            assert s.lookup(Membership.PATH) is a.team
            assert s.lookup(CapabilityRepository.PATH) is a.repository
            assert s.lookup(SingleItemAuction.PATH) is a.allocator
            assert s.lookup(MissionControl.PATH) is a.mission_control
            assert a.mission_control.slot is not None
            assert a.clock is t.clock
            assert a.repository.providers(COUNT.identity) == {"a"}
            await until(lambda: a.host.root.state is State.RUNNING, "the host tree to tick")


async def test_run_mission_returns_the_result_and_shuts_the_tree_down() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team() as t:
            a = await t.add("a", [count_impl("a", 5.0, probe)])
            await t.add("b", [count_impl("b", 1.0, probe, after=3)])
            await t.converged()
            node = COUNT.node_type()("count", inputs={"x": 4})
            root = ReactiveSequence("root", children=[node])
            assert await a.run_mission(root) is State.SUCCEEDED
            assert node.assignments == ["b"]
            assert node.outputs == {"y": 4, "ticks": 3, "robot": "b"}
            assert root.state is State.SHUTDOWN
            assert s_lookup_none(a, "tree:root")


def s_lookup_none(agent: Agent, path: str) -> bool:
    return agent.system.lookup(path) is None


async def test_cancelling_a_running_mission_releases_the_executor() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team() as t:
            a, b = await t.origin_and_executor(probe)
            node = COUNT.node_type()("count", inputs={"x": 1})
            task = asyncio.get_running_loop().create_task(
                a.run_mission(ReactiveSequence("root", children=[node]))
            )
            await until(lambda: node.state is State.RUNNING, "the remote run")
            task.cancel()
            with pytest.raises(asyncio.CancelledError):
                await task
            await until(
                lambda: (
                    not b.mission_control.host.hosted and b.mission_control.body.running is None
                ),
                "b to be released",
            )
            await until(lambda: probe.live("b") == 0, "b's run to be shut down")


async def test_an_agent_leaving_mid_work_cleans_up_both_sides() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team() as t:
            a = await t.add("a", [count_impl("a", 1.0, probe)])
            b = await t.add("b", [count_impl("b", 1.0, probe)])
            await t.converged()
            # a runs one capability itself and b runs one for a.
            n1 = COUNT.node_type()("one", inputs={"x": 1})
            n2 = COUNT.node_type()("two", inputs={"x": 2})
            tree1 = a.mission(ReactiveSequence("r1", children=[n1]))
            tree2 = a.mission(ReactiveSequence("r2", children=[n2]))
            await tick_until(tree1, lambda _s: n1.state is State.RUNNING, "n1 running")
            await tick_until(tree2, lambda _s: n2.state is State.RUNNING, "n2 running")
            assert {n1.assignments[0], n2.assignments[0]} == {"a", "b"}
            # The origin leaves (its trees are left running): b drops what it ran for a.
            await t.remove("a")
            await until(lambda: not b.mission_control.host.hosted, "b to drop a's run")
            assert b.mission_control.body.running is None
            assert t.seen("b", "a")[-1] is TeamEvent.LEFT
            await until(lambda: probe.live("a") == 0 and probe.live("b") == 0, "no live runs")


async def test_agent_entry_failure_leaves_nothing_running() -> None:
    with anyio.fail_after(10):
        async with team() as t:
            await t.add("a")
            clash: dict[str, Any] = {"team": Membership("x")}  # a path the agent uses itself
            broken = Agent("b", transport=t.net.transport("b"), clock=t.clock, actors=clash)
            with pytest.raises(ValueError, match="already lives"):
                async with broken:
                    pass
            assert not broken.system.running
