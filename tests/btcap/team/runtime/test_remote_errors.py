"""An implementation that raises on another robot is told to the origin's user: the
capability fails there with the executor's words (which node raised what), once, as a
NodeErrorWarning and a log line naming the robot, the implementation and the fix."""

from __future__ import annotations

import warnings

import anyio
from capfixtures import step, team, tick_until
from structlog.testing import capture_logs

from btcap import Leaf, NodeErrorWarning, ReactiveSequence, State, UnassignableWarning
from btcap.team.capabilities.capability import CapabilityInterface
from btcap.team.capabilities.implementation import Implementation
from btcap.team.capabilities.proxies import RemoteExecution

BARE = CapabilityInterface("Bare")


class _Boom(Leaf):
    def on_tick(self) -> State:
        raise RuntimeError("actuator fault")


def _told_of_b(caught: list[warnings.WarningMessage]) -> list[str]:
    """The warnings about the capability's run on b (b's own node warning is b's)."""
    return [
        str(w.message)
        for w in caught
        if issubclass(w.category, NodeErrorWarning) and "ran on robot 'b'" in str(w.message)
    ]


async def test_an_exception_on_the_executor_is_told_at_the_origin_once() -> None:
    with anyio.fail_after(10):
        async with team() as t:
            a = await t.add("a")
            await t.add("b", [Implementation("bare-b", BARE, lambda: _Boom("boom"))])
            await t.converged(BARE.identity)
            node = BARE.node_type()("bare")
            tree = a.mission(ReactiveSequence("root", children=[node]))
            seen: list[RemoteExecution] = []

            def done(s: State) -> bool:
                if isinstance(node.execution, RemoteExecution):
                    seen.append(node.execution)
                return s is not State.RUNNING

            with warnings.catch_warnings(record=True) as caught, capture_logs() as logs:
                warnings.simplefilter("always")
                assert await tick_until(tree, done) is State.FAILED
                for _ in range(3):  # a failed capability stays failed, told once
                    assert tree.tick() is State.FAILED
            assert node.assignments == ["b"]
            assert seen
            told = _told_of_b(caught)
            assert len(told) == 1, told
            # what raised, where, and what to do about it
            for words in ("'root/bare'", "bare-b", "RuntimeError", "actuator fault", "Fix"):
                assert words in told[0], (words, told[0])
            at_origin = [e for e in logs if e["event"] == "mission.remote_error"]
            assert len(at_origin) == 1, logs
            assert at_origin[0]["robot"] == "b"
            assert "actuator fault" in at_origin[0]["detail"]
            # the executor's report carried it (the origin's tracked detail)
            assert "RuntimeError" in seen[-1].tracked.detail
            await tree.shutdown()


async def test_a_plain_failure_on_the_executor_is_no_error_at_the_origin() -> None:
    from btcap import AlwaysFailure

    with anyio.fail_after(10):
        async with team() as t:
            a = await t.add("a")
            await t.add("b", [Implementation("bare-b", BARE, lambda: AlwaysFailure("no"))])
            await t.converged(BARE.identity)
            node = BARE.node_type()("bare")
            tree = a.mission(ReactiveSequence("root", children=[node]))
            with warnings.catch_warnings(record=True) as caught, capture_logs() as logs:
                warnings.simplefilter("always")
                assert await tick_until(tree, lambda s: s is not State.RUNNING) is State.FAILED
            assert not [w for w in caught if issubclass(w.category, NodeErrorWarning)]
            assert not [e for e in logs if e["event"] == "mission.remote_error"]
            await tree.shutdown()


class _NoDevice(Leaf):
    """An implementation whose device is not there: its setup raises at every award."""

    def on_setup(self) -> None:
        raise ConnectionError("gripper not connected")

    def on_tick(self) -> State:
        return State.SUCCEEDED


async def test_an_award_declined_for_good_is_a_capability_nobody_can_take() -> None:
    """b bids (it could) but declines every award (its setup fails): the origin's user is
    told as for a capability nobody can take, with b's reason, not left waiting in
    silence as if b were only busy."""
    with anyio.fail_after(10):
        async with team() as t:
            a = await t.add("a")
            await t.add("b", [Implementation("bare-b", BARE, lambda: _NoDevice("nd"))])
            await t.converged(BARE.identity)
            node = BARE.node_type()("bare")
            tree = a.mission(ReactiveSequence("root", children=[node]))

            def told() -> list[str]:
                return [
                    str(w.message)
                    for w in caught
                    if issubclass(w.category, UnassignableWarning)
                    and "setup of 'bare-b' failed" in str(w.message)
                ]

            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                for _ in range(400):
                    tree.tick()
                    if told():
                        break
                    await step()
            assert node.assignments == []
            assert len(told()) == 1
            assert "gripper not connected" in told()[0]
            await tree.shutdown()
