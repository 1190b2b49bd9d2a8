"""Capability interfaces, implementations, IO bridges, and local execution on one robot."""

from __future__ import annotations

from typing import Any

import anyio
import pytest
from capfixtures import COUNT, Probe, count_impl, step, team, tick_until, until
from structlog.testing import capture_logs

from btcap import (
    AlwaysSuccess,
    Parallel,
    ReactiveSequence,
    State,
    Tree,
    TreeError,
    UnassignableWarning,
)
from btcap.actors import ActorSystem
from btcap.bt.utility import CANNOT
from btcap.team.capabilities.capability import (
    ASSIGNER,
    Capability,
    CapabilityInterface,
    InputBridge,
    OutputBridge,
)
from btcap.team.capabilities.execution import AssignmentRequest
from btcap.team.capabilities.implementation import Implementation, Precondition, Scope
from btcap.team.capabilities.proxies import LocalExecution
from btcap.team.capabilities.unassignable import nobody_able

# -- interfaces --------------------------------------------------------------------------


def test_interface_rejects_options_with_a_clear_error() -> None:
    with pytest.raises(TreeError, match=r"'Move'.*no options.*speed.*make them inputs"):
        CapabilityInterface("Move", inputs={"goal": float}, options={"speed": float})


def test_interface_name_must_be_an_identifier() -> None:
    with pytest.raises(TreeError, match="identifier"):
        CapabilityInterface("move to", inputs={})


def test_identity_is_name_plus_port_names_and_types() -> None:
    a = CapabilityInterface("Go", inputs={"x": int, "y": float}, outputs={"ok": bool})
    b = CapabilityInterface(
        "Go", inputs={"y": float, "x": int}, outputs={"ok": bool}, description="other text"
    )
    assert a.identity == b.identity == "Go(x:int,y:float)->(ok:bool)"
    assert repr(a) == "CapabilityInterface(Go(x:int,y:float)->(ok:bool))"
    differs = [
        CapabilityInterface("Go", inputs={"x": int, "y": int}, outputs={"ok": bool}),
        CapabilityInterface("Go", inputs={"x": int, "z": float}, outputs={"ok": bool}),
        CapabilityInterface("Go", inputs={"x": int, "y": float}, outputs={}),
        CapabilityInterface("Went", inputs={"x": int, "y": float}, outputs={"ok": bool}),
    ]
    assert len({a.identity, *(d.identity for d in differs)}) == 5


def test_node_type_is_a_cached_capability_subclass_with_the_interface_ports() -> None:
    cls = COUNT.node_type()
    assert cls is COUNT.node_type()
    assert issubclass(cls, Capability)
    assert cls.__name__ == "Count"
    assert cls.interface() is COUNT
    assert cls.__doc__ == COUNT.description
    node = cls("c", inputs={"x": 3})
    assert set(node.input_ports) == {"x", "stop"}
    assert set(node.output_ports) == {"y", "ticks", "robot"}
    assert node.inputs == {"x": 3, "stop": False}
    assert node.options == {"local_only": False, "retry_s": 10.0, "assignment_timeout_s": 0.0}
    assert node.execution is None
    with pytest.raises(TreeError, match="unknown option"):
        cls("c", speed=2.0)
    with pytest.raises(TreeError, match="input 'x'"):
        cls("c", inputs={"x": "three"})


def test_bridge_types_mirror_the_interface() -> None:
    ib_t, ob_t = COUNT.bridge_types()
    assert (ib_t, ob_t) == COUNT.bridge_types()
    assert ib_t.__name__ == "CountInputs"
    assert ob_t.__name__ == "CountOutputs"
    ib, ob = ib_t(name="in"), ob_t(name="out")
    assert ib.interface is COUNT
    assert ob.interface is COUNT
    assert ib.output_ports == COUNT.inputs
    assert not ib.input_ports
    assert set(ob.input_ports) == {"y", "ticks", "robot"}
    assert not ob.output_ports
    assert not any(p.required for p in ob.input_ports.values())
    # The generic bridges take the interface explicitly, and need one.
    assert InputBridge("in", interface=COUNT).interface is COUNT
    with pytest.raises(TreeError, match="needs the capability interface"):
        OutputBridge(name="out")


def _impl(build: Any, iface: CapabilityInterface = COUNT) -> Implementation:
    return Implementation("impl", iface, build)


def test_bridges_must_be_for_the_implemented_interface() -> None:
    other = CapabilityInterface("Count", inputs={"x": float, "stop": bool}, outputs={})

    def wrong_bridge() -> Tree:
        ib = other.bridge_types()[0](name="in")
        return Tree(ReactiveSequence("s", children=[ib, COUNT.bridge_types()[1](name="out")]))

    with pytest.raises(TreeError, match=r"bridge 's/in' is for Count\(stop:bool,x:float\)"):
        _impl(wrong_bridge).instantiate()


def test_implementation_needs_its_bridges_once() -> None:
    ib_t, ob_t = COUNT.bridge_types()
    with pytest.raises(TreeError, match="inputs need an InputBridge"):
        _impl(lambda: ReactiveSequence("s", children=[ob_t(name="out")])).instantiate()
    with pytest.raises(TreeError, match="outputs need an OutputBridge"):
        _impl(lambda: ReactiveSequence("s", children=[ib_t(name="in")])).instantiate()
    with pytest.raises(TreeError, match="at most one bridge"):
        _impl(
            lambda: ReactiveSequence("s", children=[ib_t(name="a"), ib_t(name="b"), ob_t(name="o")])
        ).instantiate()
    # An interface without ports needs no bridges at all.
    bare = CapabilityInterface("Bare")
    run = _impl(lambda: AlwaysSuccess("ok"), bare).instantiate()
    assert run.input_bridge is None
    assert run.output_bridge is None
    assert run.step({}) == (State.SUCCEEDED, {})


def test_implementation_run_feeds_inputs_and_collects_outputs_every_step() -> None:
    probe = Probe()
    run = count_impl("r", 0.0, probe, k=3).instantiate()
    seen = [run.step({"x": x, "stop": False}) for x in (1, 2, 5)]
    assert [s for s, _ in seen] == [State.RUNNING] * 3
    assert [o["y"] for _, o in seen] == [3, 6, 15]
    assert [o["ticks"] for _, o in seen] == [1, 2, 3]
    assert run.step({"x": 7, "stop": True}) == (
        State.SUCCEEDED,
        {"y": 21, "ticks": 4, "robot": "r"},
    )


def test_implementation_cost_adds_bid_to_utility_and_none_means_cannot() -> None:
    probe = Probe()
    assert count_impl("r", 2.5, probe).cost({"x": 1}) == 2.5
    assert count_impl("r", lambda inp: None, probe).cost({"x": 1}) is None
    assert count_impl("r", lambda inp: inp["x"] * 2.0, probe).cost({"x": 4}) == 8.0

    class Never(AlwaysSuccess):
        def utility(self) -> Any:
            return CANNOT

    assert Implementation("n", CapabilityInterface("Bare"), lambda: Never("n")).cost({}) is None


def test_capability_outside_an_agent_errors_with_a_hint() -> None:
    node = COUNT.node_type()("c", inputs={"x": 1})
    tree = Tree(ReactiveSequence("root", children=[node]))
    assert tree.tick() is State.FAILED
    assert node.state is State.ERROR
    assert isinstance(node.error, TreeError)
    assert "MissionControl" in str(node.error)


# -- local execution ---------------------------------------------------------------------


async def test_lone_robot_runs_capability_locally_with_io_every_tick() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team() as t:
            a = await t.add("a", [count_impl("a", 1.0, probe, k=2)])
            node = COUNT.node_type()("count", inputs={"x": 1})
            tree = a.mission(ReactiveSequence("root", children=[node]))
            await tick_until(tree, lambda _s: node.state is State.ASSIGNED, "assigned")
            ex = node.execution
            assert isinstance(ex, LocalExecution)
            assert ex.robot == "a"
            assert a.mission_control.body.running == ex.id
            assert node.assignments == ["a"]
            out = a.allocator.outcomes[-1]
            assert out is not None
            assert [b.robot for b in out.ranking] == ["a"]
            # Every tick: the input goes in, the implementation ticks, the output comes back.
            for step, x in enumerate((1, 4, 9, -2), start=1):
                node.set_input("x", x)
                assert tree.tick() is State.RUNNING
                assert node.state is State.RUNNING
                assert node.outputs == {"y": 2 * x, "ticks": step, "robot": "a"}
            assert probe.ticks["a"] == 4
            node.set_input("stop", True)
            assert tree.tick() is State.SUCCEEDED
            assert node.outputs["ticks"] == 5
            assert node.execution is None
            assert a.mission_control.body.running is None
            assert "Count" in a.repository.succeeded
            await until(lambda: probe.live("a") == 0, "the run to be shut down")
            # The result is kept until reset: ticking again does not re-run.
            assert tree.tick() is State.SUCCEEDED
            assert probe.ticks["a"] == 5
            await tree.shutdown()


async def test_local_execution_pause_and_reset_release_the_robot() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team() as t:
            a = await t.add("a", [count_impl("a", 1.0, probe)])
            node = COUNT.node_type()("count", inputs={"x": 1})
            tree = a.mission(ReactiveSequence("root", children=[node]))
            await tick_until(tree, lambda _s: node.state is State.RUNNING, "running")
            tree.untick()
            assert node.state is State.PAUSED
            assert probe.unticks["a"] == 1
            assert a.mission_control.body.running is not None  # paused work keeps the robot
            assert tree.tick() is State.RUNNING
            tree.reset()
            assert node.execution is None
            assert node.state in {State.IDLE}
            assert a.mission_control.body.running is None
            await until(lambda: probe.live("a") == 0, "the run to be shut down")
            # Reset forgets the result: the next tick runs a fresh auction and execution.
            await tick_until(tree, lambda _s: node.state is State.RUNNING, "running again")
            assert node.assignments == ["a", "a"]
            await tree.shutdown()
            assert a.mission_control.body.running is None
            await until(lambda: probe.live("a") == 0, "the second run to be shut down")


async def test_local_only_never_leaves_the_robot_and_waits_when_it_cannot() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team() as t:
            a = await t.add("a", [count_impl("a", 9.0, probe)])
            await t.add("b", [count_impl("b", 1.0, probe)])
            c = await t.add("c")
            await t.converged()
            node = COUNT.node_type()("count", inputs={"x": 1}, local_only=True)
            tree = a.mission(ReactiveSequence("root", children=[node]))
            await tick_until(tree, lambda _s: node.state is State.RUNNING, "running")
            assert node.assignments == ["a"]  # b is cheaper, but local_only
            await tree.shutdown()
            # A robot without an implementation stays unassigned (retrying), never errors.
            lonely = COUNT.node_type()("count", inputs={"x": 1}, local_only=True, retry_s=0.1)
            tree2 = c.mission(ReactiveSequence("root2", children=[lonely]))
            for _ in range(5):
                assert tree2.tick() is State.RUNNING
                assert lonely.state is State.UNASSIGNED
            assert c.mission_control.stats.unassigned >= 1
            await tree2.shutdown()


# -- nobody can do it ------------------------------------------------------------------------


async def test_a_capability_nobody_can_run_says_why_at_a_falling_rate() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        need = (Precondition("Scan", Scope.LOCAL),)
        async with team() as t:
            a = await t.add("a")
            await t.add("b", [count_impl("b", 1.0, probe, preconditions=need)])
            await t.converged()
            node = COUNT.node_type()("count", inputs={"x": 1}, retry_s=0.1)
            tree = a.mission(ReactiveSequence("root", children=[node]))
            with capture_logs() as logs, pytest.warns(UnassignableWarning) as told:
                await tick_until(tree, lambda _s: node._waits >= 5, "five empty auctions")
            waits = [e for e in logs if e["event"] == "capability.unassigned"]
            assert [e["auctions"] for e in waits] == [1, 2, 4]
            assert waits[0]["why"] == {"b": "precondition Scan (local) not met"}
            [w] = told  # once, visible without logging configured
            assert str(w.message).startswith(
                "capability 'root/count' (Count): nobody in the team can take it "
                "(b: precondition Scan (local) not met). It waits unassigned"
            )
            assert node.state is State.UNASSIGNED
            await tree.shutdown()


async def test_no_implementation_in_the_team_is_named() -> None:
    with anyio.fail_after(10):
        async with team() as t:
            a = await t.add("a")
            node = COUNT.node_type()("count", inputs={"x": 1})
            tree = a.mission(ReactiveSequence("root", children=[node]))
            with capture_logs() as logs:
                tree.tick()
                tree.tick()
            [wait] = [e for e in logs if e["event"] == "capability.unassigned"]
            assert wait["why"] == {"team": "no live member implements Count"}
            await tree.shutdown()


async def test_an_assignment_timeout_turns_the_wait_into_a_failure() -> None:
    with anyio.fail_after(10):
        async with team() as t:
            a = await t.add("a")
            node = COUNT.node_type()("count", inputs={"x": 1}, assignment_timeout_s=1.0)
            tree = a.mission(ReactiveSequence("root", children=[node]))
            start = a.clock.now()
            with pytest.warns(UnassignableWarning) as told:
                assert await tick_until(tree, lambda s: s is not State.RUNNING) is State.FAILED
            assert a.clock.now() - start >= 1.0
            assert [str(w.message).split(":")[0] for w in told] == [
                "capability 'root/count' (Count)",  # nobody implements it
                "capability 'root/count' (Count) failed",  # within assignment_timeout_s of 1 s
            ]
            assert tree.tick() is State.FAILED  # kept until reset
            tree.reset()
            assert tree.tick() is State.RUNNING  # waits (and counts) afresh
            await tree.shutdown()


async def test_waiting_work_goes_to_a_robot_the_moment_it_comes_free() -> None:
    """No retry timer: the robot's heartbeat says it came free, and the waiting capability
    auctions again at once (retry_s is only a fallback when nothing changes)."""
    with anyio.fail_after(10):
        probe = Probe()
        async with team() as t:
            a = await t.add("a")
            b = await t.add("b", [count_impl("b", 1.0, probe)])
            await t.converged()
            first = COUNT.node_type()("first", inputs={"x": 1})
            second = COUNT.node_type()("second", inputs={"x": 2}, retry_s=1000.0)
            tree = a.mission(Parallel("both", children=[first, second]))
            await tick_until(tree, lambda _s: first.state is State.RUNNING, "first runs")
            await tick_until(tree, lambda _s: second._waits >= 1, "second found b busy")
            first.set_input("stop", True)
            await tick_until(tree, lambda _s: first.state is State.SUCCEEDED, "first done")
            freed = a.clock.now()
            await tick_until(tree, lambda _s: second.state is State.RUNNING, "second runs")
            assert a.clock.now() - freed < 1.0  # a heartbeat or two, not 1000 s
            assert b.mission_control.stats.hosted == 2
            await tree.shutdown()


async def test_paused_time_does_not_count_towards_the_assignment_timeout() -> None:
    with anyio.fail_after(20):
        probe = Probe()
        async with team(reevaluate_s=None) as t:
            a = await t.add("a")
            node = COUNT.node_type()("count", inputs={"x": 1}, assignment_timeout_s=5.0)
            tree = a.mission(ReactiveSequence("root", children=[node]))
            tree.tick()
            tree.untick()  # paused by its parent for 10 clock seconds
            for _ in range(200):
                await step()
            await t.add("b", [count_impl("b", 1.0, probe)])
            await t.converged()
            assert tree.tick() is not State.FAILED  # the wait starts again on resuming
            await tick_until(tree, lambda _s: node.state is State.RUNNING, "assigned to b")
            await tree.shutdown()


# -- the assigner ------------------------------------------------------------------------


class _Recorder:
    """An assigner that records what it is asked and never finds anyone."""

    changes = 0

    def __init__(self) -> None:
        self.asked: list[tuple[str, dict[str, Any], bool]] = []

    def request_assignment(
        self,
        node: Capability,
        inputs: dict[str, Any],
        *,
        local_only: bool = False,
        exclude: frozenset[str] = frozenset(),
    ) -> AssignmentRequest:
        self.asked.append((node.path, inputs, local_only))
        return AssignmentRequest()


async def test_a_capability_node_asks_the_assigner_its_system_provides() -> None:
    """Found by its typed service key, not by an actor path: whatever lives at
    "mission_control" is not asked, and any assigner the system provides is."""
    with anyio.fail_after(5):
        async with ActorSystem("a") as system:
            lost = Tree(COUNT.node_type()("count", inputs={"x": 1}), name="lost")
            lost.attach(system)
            with capture_logs() as logs:  # the node's error ends its tick, logged
                assert lost.tick() is State.ERROR
            assert "running MissionControl" in str(logs[0]["exc_info"])
            recorder = _Recorder()
            system.services.provide(ASSIGNER, recorder)
            tree = Tree(COUNT.node_type()("count", inputs={"x": 2}, local_only=True))
            tree.attach(system)
            assert tree.tick() is State.UNASSIGNED
            assert recorder.asked == [("count", {"x": 2, "stop": False}, True)]


def test_inputs_from_the_wire_are_converted_and_a_wrong_one_named_lazily() -> None:
    from btcap import Port

    iface = CapabilityInterface(
        "Go", inputs={"x": int, "path": tuple[float, ...], "any": Port(Any, None)}
    )
    named: list[str] = []

    def where() -> str:
        named.append("asked")
        return "call for bids a#1"

    got = iface.convert_inputs({"x": 3, "path": [1, 2.5], "any": [1]}, where)
    assert got == {"x": 3, "path": (1.0, 2.5), "any": [1]}
    assert iface.convert_inputs({}, where) == {"x": None, "path": None, "any": None}
    assert named == []  # the text is made only for an error
    with pytest.raises(TreeError, match=r"^call for bids a#1 input 'x': expected int, got str"):
        iface.convert_inputs({"x": "three"}, where)
    with pytest.raises(TreeError, match=r"^award e input 'path': expected tuple"):
        iface.convert_inputs({"path": 5}, "award e")


def test_inputs_from_the_wire_are_held_to_their_ports_constraints() -> None:
    import msgspec

    from btcap import Port

    iface = CapabilityInterface(
        "Go",
        inputs={
            "speed": Port(float, 1.0, meta=msgspec.Meta(ge=0, le=2)),
            "tag": Port(str, "", meta=msgspec.Meta(max_length=4)),
        },
        outputs={"count": Port(int, 0, meta=msgspec.Meta(ge=0))},
    )
    assert iface.convert_inputs({"speed": 2, "tag": "ab"}, "x") == {"speed": 2.0, "tag": "ab"}
    with pytest.raises(TreeError, match=r"^call for bids a#1 input 'speed': must be >= 0 and <= 2"):
        iface.convert_inputs({"speed": 5.0}, "call for bids a#1")
    with pytest.raises(TreeError, match=r"^award e input 'tag': .*length"):
        iface.convert_inputs({"tag": "x" * 5000}, "award e")
    with pytest.raises(TreeError, match=r"^report r output 'count': must be >= 0, got -1"):
        iface.convert_outputs({"count": -1}, "report r")


def test_only_an_auction_nobody_could_win_is_news() -> None:
    """Robots able but occupied are routine (no warning); only reasons of inability from
    every robot make an UnassignableWarning."""
    assert nobody_able({"team": "no live member implements Count"})
    assert nobody_able({"b": "precondition Scan (local) not met", "c": "no remote capability slot"})
    for routine in (
        "busy",
        "took another task of the same round",
        "no answer",
        "declined the award: busy",
        "bid 5 not below 4",
    ):
        assert not nobody_able({"b": "precondition Scan (local) not met", "c": routine})
