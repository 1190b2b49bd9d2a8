"""The capability repository: local content, and the team view converging by gossip."""

from __future__ import annotations

import anyio
import pytest
from capfixtures import COUNT, Probe, count_impl, team, tick_until, until

from btcap import ReactiveSequence, State, TreeError
from btcap.actors import ActorSystem
from btcap.team.capabilities.capability import CapabilityInterface
from btcap.team.membership.membership import Membership
from btcap.team.membership.repository import CapabilityRepository
from btcap.team.messages import Heartbeat, RepositoryQuery, RepositoryState
from btcap.team.runtime.protocol import protocol_registry
from btcap.transports import Address, InProcessNetwork

OTHER = CapabilityInterface("Other", inputs={"x": int, "stop": bool}, outputs={"y": int})


def test_local_content_and_version() -> None:
    probe = Probe()
    repo = CapabilityRepository("a")
    assert repo.version == 0
    assert repo.providers(COUNT.identity) == set()
    repo.add_implementation(count_impl("a", 1.0, probe, name="one"))
    repo.add_implementation(count_impl("a", 2.0, probe, name="two"))
    assert repo.version == 2
    assert [i.name for i in repo.local_implementations("Count")] == ["one", "two"]
    assert repo.local_implementations("Count", "Count(x:float)->()") == []
    assert repo.providers(COUNT.identity) == {"a"}
    assert repo.state() == RepositoryState("a", 2, {"Count": COUNT.identity}, [])
    with pytest.raises(TreeError, match="'one' exists"):
        repo.add_implementation(count_impl("a", 1.0, probe, name="one"))
    clash = CapabilityInterface("Count", inputs={"x": float})
    with pytest.raises(TreeError, match="already"):
        repo.add_interface(clash)
    with pytest.raises(TreeError, match="no implementation Count/three"):
        repo.remove_implementation("Count", "three")
    repo.remove_implementation("Count", "one")
    repo.remove_implementation("Count", "two")
    assert repo.providers(COUNT.identity) == set()
    assert repo.state().interfaces == {}
    repo.record_success("Count")
    repo.record_success("Count")
    assert repo.version == 5
    assert repo.succeeded_anywhere("Count")
    assert not repo.succeeded_anywhere("Other")


async def test_team_view_converges_and_follows_changes() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team() as t:
            a = await t.add("a", [count_impl("a", 1.0, probe)])
            b = await t.add("b", [count_impl("b", 1.0, probe)])
            c = await t.add("c")
            await t.converged()
            for x in (a, b, c):
                assert x.repository.providers(COUNT.identity) == {"a", "b"}
            # Added at run time: broadcast at once.
            c.repository.add_implementation(count_impl("c", 1.0, probe))
            await t.converged()
            assert a.repository.team["c"].interfaces == {"Count": COUNT.identity}
            # Removed at run time.
            b.repository.remove_implementation("Count", "count-b")
            await until(lambda: a.repository.providers(COUNT.identity) == {"a", "c"})
            # A leaving robot leaves the view.
            await t.remove("c")
            await until(
                lambda: (
                    a.repository.providers(COUNT.identity) == {"a"} and "c" not in b.repository.team
                )
            )


async def test_a_lost_update_is_repaired_by_the_heartbeat_version() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team() as t:
            a = await t.add("a")
            b = await t.add("b")
            await t.converged()
            t.net.isolate("b")
            b.repository.add_implementation(count_impl("b", 1.0, probe))  # broadcast lost
            t.net.heal("b")
            assert a.repository.providers(COUNT.identity) == set()
            await until(lambda: a.repository.providers(COUNT.identity) == {"b"})
            assert a.repository.team["b"].version == b.repository.version


async def test_success_is_gossiped_for_remote_preconditions() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team() as t:
            a, b = await t.origin_and_executor(probe)
            node = COUNT.node_type()("count", inputs={"x": 1, "stop": True})
            tree = a.mission(ReactiveSequence("root", children=[node]))
            assert await tick_until(tree, lambda s: s is not State.RUNNING) is State.SUCCEEDED
            assert "Count" in b.repository.succeeded
            assert "Count" not in a.repository.succeeded  # it ran on b, not on a
            await until(lambda: a.repository.succeeded_anywhere("Count"))
            await tree.shutdown()


async def test_stale_and_self_states_are_ignored() -> None:
    with anyio.fail_after(10):
        async with team() as t:
            a = await t.add("a")
            b = await t.add("b")
            await t.converged()
            await until(lambda: "b" in a.repository.team)
            known = a.repository.team["b"]
            to_a = Address("a", CapabilityRepository.PATH)
            b.system.tell(to_a, RepositoryState("b", known.version - 1, {"X": "X()->()"}))
            b.system.tell(to_a, RepositoryState("a", 99, {"X": "X()->()"}))  # not b's to say
            await until(lambda: a.repository.refused == 1, "the state in a's name refused")
            assert a.repository.team["b"] == known
            assert "a" not in a.repository.team
            # A query is answered, with the full state, to who asked (not whom it names).
            b.repository.team.pop("a")
            a.system.tell(to_a, RepositoryQuery("b"))  # a asking itself: not answered
            b.system.tell(to_a, RepositoryQuery("zed"))
            await until(lambda: "a" in b.repository.team)


async def test_states_only_from_members_each_for_itself() -> None:
    with anyio.fail_after(10):
        async with team() as t:
            a = await t.add("a")
            b = await t.add("b")
            await t.converged()
            await until(lambda: "b" in a.repository.team)
            joined: list[str] = []
            a.repository.subscribe(joined.append)
            to_a = Address("a", CapabilityRepository.PATH)
            # A system on the network that never joined the team is not held, however many.
            async with ActorSystem("ghost", transport=t.net.transport("ghost")) as ghost:
                for i in range(50):
                    ghost.tell(to_a, RepositoryState("ghost", i, {"Count": COUNT.identity}))
                b.system.tell(to_a, RepositoryState("c", 1, {"Count": COUNT.identity}))
                await until(
                    lambda: (a.repository.early, a.repository.refused) == (50, 1), "all dropped"
                )
            assert set(a.repository.team) == {"b"}
            assert joined == []


async def test_a_stopped_repository_no_longer_listens_to_the_team(
    caplog: pytest.LogCaptureFixture,
) -> None:
    with anyio.fail_after(5):
        net = InProcessNetwork(protocol_registry())
        async with (
            ActorSystem("a", transport=net.transport("a")) as system,
            ActorSystem("b", transport=net.transport("b")) as other,
        ):
            members = Membership("a")
            system.spawn(members, Membership.PATH)
            repo = CapabilityRepository("a", team=members)
            system.spawn(repo, CapabilityRepository.PATH)
            seen: list[str] = []
            members.subscribe(lambda event, robot: seen.append(robot))
            system.stop(repo)
            other.tell(members.address, Heartbeat("b", 1, 0))
            await until(lambda: seen == ["b"], "b to join")  # reported to the other listener
            # A stopped repository still subscribed would fail in its listener.
            assert "listener_failed" not in caplog.text
