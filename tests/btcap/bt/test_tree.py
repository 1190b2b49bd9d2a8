"""Trees: lookup, editing, observers, running on a clock, actors, shutdown, subtrees."""

from __future__ import annotations

import asyncio
from typing import Any

import anyio
import pytest
from structlog.testing import capture_logs

from btcap import (
    Action,
    AlwaysFailure,
    AlwaysRunning,
    AlwaysSuccess,
    Condition,
    Constant,
    IllegalTransition,
    Inverter,
    Leaf,
    Node,
    Parallel,
    ReactiveFallback,
    ReactiveSequence,
    Sequence,
    State,
    Subtree,
    Tree,
    TreeError,
    TreeTimeout,
    Utility,
    Wait,
    protocol_registry,
)
from btcap.actors import ActorFailed, ActorSystem, Clock, ManualClock
from btcap.bt.messages import NodeStatus, Reset, Setup, Shutdown, Tick, Untick
from btcap.transports import Envelope, InProcessNetwork, Kind

S, F, R = State.SUCCEEDED, State.FAILED, State.RUNNING


class Leafy(Leaf):
    """Returns ``result`` (settable) and counts its ticks."""

    def __init__(self, name: str, result: State = S) -> None:
        super().__init__(name)
        self.result = result
        self.ticks = 0

    def on_tick(self) -> State:
        self.ticks += 1
        return self.result


class Stamp(Leaf):
    """Records the clock time of every tick; succeeds after ``n`` ticks."""

    def __init__(self, name: str = "stamp", n: int = 1_000_000) -> None:
        super().__init__(name)
        self.n = n
        self.times: list[float] = []

    def on_tick(self) -> State:
        self.times.append(self.clock.now())
        return S if len(self.times) >= self.n else R


def state_of(node: Node) -> State:
    """A node's state, read afresh (mypy would keep an earlier narrowing)."""
    return node.state


async def settle() -> None:
    for _ in range(5):
        await asyncio.sleep(0)


def other_tasks() -> set[asyncio.Task[Any]]:
    current = asyncio.current_task()
    return {t for t in asyncio.all_tasks() if t is not current}


def sample_tree() -> Tree:
    return Tree(
        ReactiveSequence(
            "root",
            children=[
                ReactiveFallback("fb", children=[Leafy("a", F), Leafy("b")]),
                Inverter("inv", children=[Leafy("c", F)]),
            ],
        )
    )


# -- lookup ---------------------------------------------------------------------------


def test_find_by_path() -> None:
    tree = sample_tree()
    assert tree.find("root") is tree.root
    assert tree.find("root/fb/b").name == "b"
    assert tree.find("root/inv/c").path == "root/inv/c"
    assert [n.name for n in tree.nodes()] == ["root", "fb", "a", "b", "inv", "c"]
    assert tree.name == "root"
    assert Tree(AlwaysSuccess("x"), name="named").name == "named"


@pytest.mark.parametrize(
    ("path", "message"),
    [
        ("nope", "no node 'nope' \\(root is 'root'\\)"),
        ("root/fb/z", "no node 'root/fb/z' \\('root/fb' has no child 'z'\\)"),
        ("root/fb/a/deeper", "'root/fb/a' has no child 'deeper'"),
        ("", "no node ''"),
    ],
)
def test_find_unknown_paths(path: str, message: str) -> None:
    with pytest.raises(TreeError, match=message):
        sample_tree().find(path)


def test_a_node_belongs_to_one_tree() -> None:
    tree = sample_tree()
    with pytest.raises(TreeError, match="'root' already belongs to tree 'root'"):
        Tree(tree.root)
    a = tree.find("root/fb/a")
    assert a.tree is tree


# -- editing ----------------------------------------------------------------------------


def test_insert_subtree_when_not_running() -> None:
    tree = sample_tree()
    new = ReactiveSequence("new", children=[Leafy("x"), Leafy("y")])
    tree.insert("root/fb", new, 0)
    assert tree.find("root/fb/new/y").tree is tree
    assert [c.name for c in tree.find("root/fb").children] == ["new", "a", "b"]
    assert tree.tick() is S


def test_insert_into_a_set_up_tree_sets_the_subtree_up() -> None:
    tree = sample_tree()
    assert tree.tick() is S
    x = Leafy("x", R)
    tree.insert(tree.root, ReactiveSequence("more", children=[x]))
    assert x.state is State.IDLE
    assert tree.tick() is R
    assert x.ticks == 1
    assert tree.errors() == []


def test_insert_below_a_running_node_raises() -> None:
    tree = Tree(ReactiveSequence("root", children=[Leafy("busy", R)]))
    tree.tick()
    with pytest.raises(IllegalTransition, match="while it is running"):
        tree.insert("root", Leafy("x"))
    assert [c.name for c in tree.root.children] == ["busy"]


def test_failed_insert_leaves_the_tree_unchanged() -> None:
    tree = sample_tree()
    other = Tree(Leafy("other_root"))
    wrapper = Inverter("wrapper", children=[other.root])
    with pytest.raises(TreeError, match="already belongs to tree 'other_root'"):
        tree.insert("root", wrapper)
    assert [c.name for c in tree.root.children] == ["fb", "inv"]
    assert wrapper.parent_node is None
    assert wrapper._tree is None
    assert other.root.tree is other
    assert tree.tick() is S


def test_remove_subtree_detaches_shuts_down_and_drops_wires() -> None:
    k = Constant("k", value=1, type=int)
    cond = Condition(lambda x: x == 1, "cond", inputs={"x": int})
    tree = Tree(ReactiveSequence("root", children=[k, ReactiveSequence("sub", children=[cond])]))
    tree.wire(k, "value", cond, "x")
    assert tree.tick() is S
    removed = tree.remove("root/sub")
    assert removed.state is State.SHUTDOWN
    assert cond.state is State.SHUTDOWN
    assert removed.parent_node is None
    assert tree.wires == []
    assert cond._pulls is None
    with pytest.raises(TreeError, match="not part of a Tree"):
        _ = cond.tree
    assert [c.name for c in tree.root.children] == ["k"]
    assert tree.tick() is S
    # A removed subtree can join again, and is set up on the way in.
    tree.insert("root", removed)
    cond.set_input("x", 1)
    assert state_of(removed) is State.IDLE
    assert tree.tick() is S


def test_removing_an_active_subtree_raises() -> None:
    tree = Tree(
        ReactiveSequence("root", children=[ReactiveSequence("sub", children=[Leafy("busy", R)])])
    )
    tree.tick()
    with pytest.raises(TreeError, match="cannot remove 'root/sub' while it is running"):
        tree.remove("root/sub")
    tree.untick()
    assert tree.remove("root/sub").name == "sub"


def test_cannot_remove_the_root_or_a_stranger() -> None:
    tree = sample_tree()
    with pytest.raises(TreeError, match="cannot remove the root"):
        tree.remove("root")
    with pytest.raises(TreeError, match="is not part of tree"):
        tree.remove(Leafy("stranger"))


# -- observers --------------------------------------------------------------------------


Change = tuple[str, State, State]


def replay(start: dict[str, State], changes: list[Change]) -> dict[str, State]:
    states = dict(start)
    for path, old, new in changes:
        assert states[path] is old, f"{path}: reported {old} -> {new} but was {states[path]}"
        assert old is not new
        states[path] = new
    return states


def test_observers_see_every_state_change() -> None:
    leaf_b = Leafy("b", R)
    tree = Tree(
        ReactiveSequence(
            "root", children=[ReactiveFallback("fb", children=[Leafy("a", F), leaf_b]), Leafy("c")]
        )
    )
    changes: list[Change] = []
    tree.observe(lambda n, old, new: changes.append((n.path, old, new)))
    start = {n.path: n.state for n in tree.nodes()}

    def actual() -> dict[str, State]:
        return {n.path: n.state for n in tree.nodes()}

    tree.tick()  # setup, then a tick
    assert replay(start, changes) == actual()
    assert ("root/fb/b", State.IDLE, R) in changes
    assert ("root/c", State.UNINITIALIZED, State.IDLE) in changes
    leaf_b.result = S
    tree.tick()
    tree.untick()
    leaf_b.result = R
    tree.tick()
    tree.reset()
    tree.tick()
    tree.untick()
    assert replay(start, changes) == actual()
    n_changes = len(changes)
    tree.tick()
    tree.tick()  # no change in this one
    assert replay(start, changes) == actual()
    assert len(changes) == n_changes + 3  # root, fb and b resume


def test_observers_see_errors_and_shutdown() -> None:
    class Boom(Leaf):
        def on_tick(self) -> State:
            raise RuntimeError("no")

    tree = Tree(ReactiveSequence("root", children=[Boom("boom")]))
    changes: list[Change] = []
    tree.observe(lambda n, old, new: changes.append((n.path, old, new)))
    with capture_logs():
        tree.tick()
    assert ("root/boom", State.IDLE, State.ERROR) in changes


async def test_observers_see_shutdown() -> None:
    with anyio.fail_after(5):
        tree = sample_tree()
        changes: list[Change] = []
        tree.observe(lambda n, old, new: changes.append((n.path, old, new)))
        tree.tick()
        await tree.shutdown()
        assert ("root", S, State.SHUTDOWN) in changes
        assert len([c for c in changes if c[2] is State.SHUTDOWN]) == 6


def test_unsubscribe_and_several_observers() -> None:
    tree = sample_tree()
    tree.debug = False  # debug mode observes every node
    first: list[Change] = []
    second: list[Change] = []
    stop_first = tree.observe(lambda n, old, new: first.append((n.path, old, new)))
    stop_second = tree.observe(lambda n, old, new: second.append((n.path, old, new)))
    tree.tick()
    assert first == second != []
    stop_first()
    stop_first()  # twice is fine
    tree.reset()
    assert len(first) < len(second)
    stop_second()
    n = len(second)
    tree.tick()
    assert len(second) == n
    assert all(node._watch is None for node in tree.nodes())


def test_observers_follow_inserted_and_removed_nodes() -> None:
    tree = sample_tree()
    changes: list[Change] = []
    tree.observe(lambda n, old, new: changes.append((n.path, old, new)))
    tree.tick()
    x = Leafy("x", F)
    tree.insert("root/fb", x, 0)
    tree.tick()
    assert ("root/fb/x", State.IDLE, F) in changes
    tree.remove(x)
    changes.clear()
    x.setup()
    x.tick()
    assert changes == []


def test_an_observer_of_some_node_types_sees_only_those_and_costs_the_others_nothing() -> None:
    tree = sample_tree()
    tree.debug = False  # debug mode observes every node
    leaves: list[Change] = []
    every: list[Change] = []
    stop = tree.observe(lambda n, old, new: leaves.append((n.path, old, new)), only=Leaf)
    tree.tick()
    assert leaves
    assert all(isinstance(tree.find(path), Leaf) for path, _, _ in leaves)
    assert all(n._watch is None for n in tree.nodes() if not isinstance(n, Leaf))
    tree.observe(lambda n, old, new: every.append((n.path, old, new)))
    tree.reset()
    tree.tick()
    assert {p for p, _, _ in every} > {p for p, _, _ in leaves}
    stop()
    n = len(leaves)
    tree.reset()
    assert len(leaves) == n


def test_the_tree_version_grows_when_nodes_join_or_leave() -> None:
    tree = sample_tree()
    v = tree.version
    tree.tick()
    assert tree.version == v
    x = tree.insert("root/fb", Leafy("x", F), 0)
    assert tree.version > v
    v = tree.version
    tree.remove(x)
    assert tree.version > v


# -- running ----------------------------------------------------------------------------


async def test_run_ticks_at_the_rate_on_a_manual_clock() -> None:
    with anyio.fail_after(5):
        clock = ManualClock(start=10.0)
        stamp = Stamp(n=5)
        tree = Tree(stamp, clock=clock)
        runner = asyncio.create_task(tree.run(10))
        await settle()
        assert stamp.times == [10.0]
        await clock.advance(0.05)
        assert len(stamp.times) == 1
        await clock.advance(0.05)
        assert len(stamp.times) == 2
        await clock.advance(1.0)
        assert await runner is S
        assert stamp.times == pytest.approx([10.0, 10.1, 10.2, 10.3, 10.4])


async def test_run_stops_at_max_ticks_or_until() -> None:
    with anyio.fail_after(5):
        clock = ManualClock()
        stamp = Stamp()
        tree = Tree(stamp, clock=clock)
        runner = asyncio.create_task(tree.run(4, max_ticks=3))
        await settle()
        await clock.advance(10)
        with pytest.raises(TreeTimeout) as err:
            await runner
        assert stamp.times == [0.0, 0.25, 0.5]
        assert (err.value.limit, err.value.running, err.value.ticks) == ("max_ticks", ("stamp",), 3)
        assert err.value.state is R
        assert str(err.value) == (
            "tree 'stamp' reached its limit of 3 ticks after 3 ticks without a result and "
            "was halted; still running: stamp"
        )
        assert stamp.state is State.PAUSED

        runner = asyncio.create_task(tree.run(2, until=lambda s: len(stamp.times) >= 6))
        await settle()
        await clock.advance(10)
        assert await runner is R
        assert len(stamp.times) == 6


async def test_run_returns_the_result_and_errors() -> None:
    with anyio.fail_after(5):
        assert await Tree(AlwaysFailure(), clock=ManualClock()).run() is F

        class Boom(Leaf):
            def on_tick(self) -> State:
                raise RuntimeError("no")

        with capture_logs():
            assert await Tree(Boom(), clock=ManualClock()).run() is State.ERROR


async def test_run_on_a_fast_clock() -> None:
    with anyio.fail_after(5):
        clock = Clock(speedup=1000)
        tree = Tree(
            ReactiveSequence("root", children=[Wait("wait", seconds=0.5), AlwaysSuccess()]),
            clock=clock,
        )
        assert await tree.run(100) is S
        assert clock.now() >= 0.5


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"rate_hz": 0}, "rate_hz must be > 0, got 0"),
        ({"rate_hz": float("nan")}, "rate_hz must be > 0, got nan"),
        ({"max_ticks": 0}, "max_ticks must be >= 1 or None, got 0"),
        ({"timeout_s": 0}, "timeout_s must be > 0 or None, got 0"),
        ({"timeout_s": -1.0}, "timeout_s must be > 0 or None, got -1.0"),
    ],
)
async def test_run_rejects_bad_rates_and_limits(kwargs: dict[str, Any], message: str) -> None:
    leaf = Leafy("x")
    with anyio.fail_after(5), pytest.raises(ValueError, match=message):
        await Tree(leaf).run(**kwargs)
    assert leaf.ticks == 0


async def test_run_halts_the_tree_at_its_time_limit_and_names_the_running_nodes() -> None:
    cancelled = asyncio.Event()

    async def forever() -> None:
        try:
            await asyncio.Event().wait()
        finally:
            cancelled.set()

    with anyio.fail_after(5):
        clock = ManualClock()
        stamp = Stamp("watch")
        work = Action(forever, "work")
        root = Parallel("root", children=[Sequence("go", children=[AlwaysSuccess(), work]), stamp])
        tree = Tree(root, clock=clock)
        runner = asyncio.create_task(tree.run(10, timeout_s=0.35))
        await settle()
        await clock.advance(10)
        with pytest.raises(TreeTimeout) as err:
            await runner
        # Ticks at 0, 0.1, 0.2, 0.3; halted at 0.35 without waiting for the next tick.
        assert stamp.times == pytest.approx([0.0, 0.1, 0.2, 0.3])
        assert clock.now() == 10  # the run ended at 0.35; the advance went on
        assert err.value.limit == "timeout_s"
        assert err.value.running == ("root/go/work", "root/watch")
        assert err.value.ticks == 4
        assert "reached its time limit of 0.35 s after 4 ticks" in str(err.value)
        assert isinstance(err.value, TimeoutError)
        assert isinstance(err.value, TreeError)
        assert [n.state for n in (root, work, stamp)] == [State.PAUSED] * 3
        await asyncio.wait_for(cancelled.wait(), 1)  # the Action's work was cancelled
        assert clock.pending == 0
        await tree.shutdown()


async def test_run_names_the_running_nodes_inside_a_subtree() -> None:
    with anyio.fail_after(5):
        inner = Tree(Sequence("nav", children=[AlwaysSuccess(), AlwaysRunning("drive")]))
        tree = Tree(Sequence("root", children=[Subtree(inner, "go")]), clock=ManualClock())
        with pytest.raises(TreeTimeout) as err:
            await tree.run(10, max_ticks=1)
        assert err.value.running == ("root/go/drive",)
        assert inner.root.state is State.PAUSED


async def test_run_can_be_cancelled() -> None:
    with anyio.fail_after(5):
        clock = ManualClock()
        tree = Tree(AlwaysRunning(), clock=clock)
        runner = asyncio.create_task(tree.run(10))
        await settle()
        runner.cancel()
        with pytest.raises(asyncio.CancelledError):
            await runner
        assert clock.pending == 0


def test_tick_until_result() -> None:
    leaf = Leafy("x", R)

    class CountDown(Leaf):
        def __init__(self) -> None:
            super().__init__("countdown")
            self.left = 5

        def on_tick(self) -> State:
            self.left -= 1
            return S if self.left == 0 else R

    assert Tree(CountDown()).tick_until_result() is S
    with pytest.raises(TreeError, match="no result within 10 ticks"):
        Tree(leaf).tick_until_result(max_ticks=10)
    assert leaf.ticks == 10


def test_errors_lists_nodes_in_error() -> None:
    class Boom(Leaf):
        def on_tick(self) -> State:
            raise KeyError("k")

    boom = Boom("boom")
    tree = Tree(Parallel("root", children=[boom, Leafy("ok")], success_threshold=1))
    assert tree.errors() == []
    with capture_logs():
        tree.tick()
    assert tree.errors() == [boom]
    assert isinstance(boom.error, KeyError)
    tree.reset()
    assert tree.errors() == []


def test_untick_and_reset_of_a_tree_never_set_up_do_nothing() -> None:
    tree = sample_tree()
    tree.untick()
    tree.reset()
    assert tree.root.state is State.UNINITIALIZED


async def test_shutdown_cancels_background_work_and_leaves_no_tasks() -> None:
    with anyio.fail_after(5):
        cancelled: list[str] = []

        async def work(name: str) -> None:
            try:
                await asyncio.sleep(100)
            except asyncio.CancelledError:
                cancelled.append(name)
                raise

        tree = Tree(
            Parallel(
                "root",
                children=[Action(lambda: work("a"), "a"), Action(lambda: work("b"), "b")],
            )
        )
        before = other_tasks()
        tree.tick()
        await settle()
        assert len(other_tasks() - before) == 2
        await tree.shutdown()
        assert sorted(cancelled) == ["a", "b"]
        assert other_tasks() == before
        assert {n.state for n in tree.nodes()} == {State.SHUTDOWN}


async def test_tree_as_async_context_manager() -> None:
    with anyio.fail_after(5):
        gate = asyncio.Event()

        async def work() -> None:
            await gate.wait()

        before = other_tasks()
        async with Tree(Action(work, "work")) as tree:
            tree.tick()
            await settle()
        assert other_tasks() == before
        assert tree.root.state is State.SHUTDOWN
        # ... and it can run again afterwards.
        assert tree.tick() is R
        await tree.shutdown()


# -- actors -------------------------------------------------------------------------------


async def test_attach_makes_every_node_an_addressable_actor() -> None:
    with anyio.fail_after(5):
        async with ActorSystem("robot") as system:
            k = Constant("k", value=5, type=int)
            cond = Condition(lambda x: x > 3, "big", inputs={"x": int})
            root = ReactiveSequence("root", children=[k, Inverter("inv", children=[cond])])
            tree = Tree(root, name="mission")
            cond.set_input("x", 5)
            tree.attach(system)
            assert str(root.address) == "robot/tree:mission"
            assert str(cond.address) == "robot/tree:mission/inv/big"
            for n in tree.nodes():
                assert system.lookup(n.address.path) is n

            ref = system.ref(root.address)
            assert await ref.ask(Setup()) == NodeStatus(State.IDLE, {})
            status = await system.ref("robot/tree:mission/k").ask(Tick(), expect=NodeStatus)
            assert status == NodeStatus(S, {"value": 5})
            assert await ref.ask(Tick()) == NodeStatus(F, {})
            big = system.ref(cond.address)
            assert (await big.ask(Tick({"x": 1}))).state is F
            assert cond.inputs["x"] == 1
            assert await big.ask(Untick()) == NodeStatus(State.IDLE, {})
            assert await ref.ask(Reset()) == NodeStatus(State.IDLE, {})
            with pytest.raises(ActorFailed, match="input 'x': expected int"), capture_logs():
                await big.ask(Tick({"x": "one"}))
            assert await ref.ask(Shutdown()) == NodeStatus(State.SHUTDOWN, {})
            await tree.shutdown()
            assert not any(n.spawned for n in tree.nodes())
            assert system.lookup("tree:mission") is None


async def test_ask_before_setup_fails_with_the_illegal_transition() -> None:
    with anyio.fail_after(5):
        async with ActorSystem("robot") as system:
            tree = Tree(AlwaysSuccess("only"))
            tree.attach(system)
            with pytest.raises(ActorFailed, match=r"IllegalTransition.*call setup"), capture_logs():
                await system.ref(tree.root.address).ask(Tick())
            with pytest.raises(TreeError, match="already attached"):
                tree.attach(system)
            await tree.shutdown()


async def test_attached_tree_spawns_inserted_and_stops_removed_nodes() -> None:
    with anyio.fail_after(5):
        async with ActorSystem("robot") as system:
            tree = sample_tree()
            tree.attach(system)
            extra = ReactiveSequence("extra", children=[Leafy("x")])
            tree.insert("root", extra)
            assert system.lookup("tree:root/extra/x") is extra.children[0]
            tree.remove(extra)
            assert system.lookup("tree:root/extra") is None
            assert system.lookup("tree:root/extra/x") is None
            assert not extra.spawned
            await tree.shutdown()


async def test_attached_tree_shutdown_awaits_its_background_work() -> None:
    with anyio.fail_after(5):
        async with ActorSystem("robot") as system:
            seen: list[str] = []

            async def work() -> None:
                try:
                    await asyncio.sleep(100)
                except asyncio.CancelledError:
                    seen.append("cancelled")
                    raise

            before = other_tasks()
            tree = Tree(Action(work, "work"))
            tree.attach(system)
            tree.tick()
            await settle()
            await tree.shutdown()
            assert seen == ["cancelled"]
            assert other_tasks() == before


async def test_node_actions_from_another_system_are_refused() -> None:
    """Nodes are driven by their own robot only: another system's node actions are
    refused and counted, and the node is left as it was."""
    with anyio.fail_after(5):
        net = InProcessNetwork(protocol_registry())
        async with (
            ActorSystem(transport=net.transport("a"), registry=protocol_registry()) as a,
            ActorSystem(transport=net.transport("b"), registry=protocol_registry()) as b,
        ):
            k = Constant("k", value=[1.5, 2.5], type=tuple[float, float])
            tree = Tree(ReactiveSequence("root", children=[k]), name="t")
            tree.attach(b)
            tree.setup()
            for action in (Tick(), Untick(), Reset(), Shutdown(), Setup()):
                with pytest.raises(ActorFailed, match="Refused"), capture_logs():
                    await a.ref(k.address).ask(action, timeout=2)
            assert k.state is State.IDLE
            assert b.stats.refused == dict.fromkeys(
                ("Tick", "Untick", "Reset", "Shutdown", "Setup"), 1
            )
            # b's own actors still drive it, and its status survives the codec.
            reply = await b.ref(k.address).ask(Tick())
            assert net.codec is not None
            env = Envelope(Kind.REPLY, k.address, a.address, reply, 1)
            assert net.codec.decode(net.codec.encode(env)).msg == NodeStatus(
                S,
                {"value": [1.5, 2.5]},  # a tuple travels as a list
            )
            await tree.shutdown()


# -- subtrees -----------------------------------------------------------------------------


class Doubler(Leaf):
    INPUTS = {"x": int}
    OUTPUTS = {"y": int}

    def on_tick(self) -> State:
        self.outputs["y"] = 2 * self.inputs["x"]
        return S


def doubler_subtree(name: str = "double") -> Subtree:
    inner = Tree(ReactiveSequence("inner", children=[Doubler("d")]))
    return Subtree(inner, name, public_inputs={"x": "inner/d.x"}, public_outputs={"y": "inner/d.y"})


def test_subtree_maps_inputs_and_outputs_every_tick() -> None:
    src = Constant("src", value=1, type=int)
    sub = doubler_subtree()
    check = Condition(lambda v: v > 2, "check", inputs={"v": int})
    tree = Tree(ReactiveSequence("root", children=[src, sub, check]))
    assert sub.input_ports["x"].type is int
    assert sub.output_ports["y"].type is int
    tree.wire(src, "value", sub, "x")
    tree.wire(sub, "y", check, "v")
    assert tree.tick() is F
    assert sub.outputs == {"y": 2}
    src.options["value"] = 5
    assert tree.tick() is S
    assert sub.outputs == {"y": 10}
    assert sub.inner.find("inner/d").inputs["x"] == 5


def test_subtree_without_its_public_input_fails_validation() -> None:
    tree = Tree(ReactiveSequence("root", children=[doubler_subtree()]))
    with pytest.raises(TreeError, match="'root/double': input 'x' needs a value or a wire"):
        tree.tick()


def test_subtree_state_follows_the_inner_tree() -> None:
    leaf = Leafy("leaf", R)
    sub = Subtree(Tree(ReactiveSequence("inner", children=[leaf])), "sub")
    tree = Tree(ReactiveFallback("root", children=[sub]))
    assert tree.tick() is R
    assert sub.state is R
    tree.untick()
    assert (sub.state, leaf.state) == (State.PAUSED, State.PAUSED)
    leaf.result = F
    assert tree.tick() is F
    tree.reset()
    assert (sub.state, leaf.state) == (State.IDLE, State.IDLE)
    assert sub.name == "sub"
    assert Subtree(Tree(AlwaysSuccess("x"))).name == "x"


async def test_subtree_uses_the_outer_clock_and_is_shut_down_with_it() -> None:
    with anyio.fail_after(5):
        clock = ManualClock()
        seen: list[str] = []

        async def work() -> None:
            try:
                await asyncio.sleep(100)
            except asyncio.CancelledError:
                seen.append("cancelled")
                raise

        inner = Tree(Parallel("inner", children=[Wait("wait", seconds=1), Action(work, "work")]))
        sub = Subtree(inner, "sub")
        before = other_tasks()
        tree = Tree(ReactiveSequence("root", children=[sub]), clock=clock)
        assert tree.tick() is R
        assert inner.clock is clock
        await settle()
        await clock.advance(1)
        tree.tick()
        assert inner.find("inner/wait").state is S
        await tree.shutdown()
        assert seen == ["cancelled"]
        assert inner.root.state is State.SHUTDOWN
        assert other_tasks() == before


def test_subtree_utility_is_the_inner_trees() -> None:
    class Costly(Leaf):
        def on_tick(self) -> State:
            return S

        def utility(self) -> Utility:
            return Utility(True, 1.0, 2.0, 0.5, 0.5)

    sub = Subtree(Tree(Costly("c")))
    assert sub.utility() == Utility(True, 1.0, 2.0, 0.5, 0.5)


@pytest.mark.parametrize(
    ("inputs", "outputs", "message"),
    [
        ({"x": "inner/d"}, {}, "must look like 'node/path.port'"),
        ({"x": "inner/d.z"}, {}, "'inner/d' has no input 'z'"),
        ({}, {"y": "inner/d.x"}, "'inner/d' has no output 'x'"),
        ({"x": "inner/e.x"}, {}, "no node 'inner/e'"),
    ],
)
def test_subtree_bad_port_references(
    inputs: dict[str, str], outputs: dict[str, str], message: str
) -> None:
    inner = Tree(ReactiveSequence("inner", children=[Doubler("d")]))
    with pytest.raises(TreeError, match=message):
        Subtree(inner, "sub", public_inputs=inputs, public_outputs=outputs)


def test_subtree_inner_setup_failure_fails_the_outer_setup() -> None:
    inner = Tree(ReactiveSequence("inner", children=[Inverter("empty")]))
    tree = Tree(ReactiveSequence("root", children=[Subtree(inner, "sub")]))
    with capture_logs(), pytest.raises(TreeError, match="root/sub: TreeError: node 'inner/empty'"):
        tree.tick()


def helper_typecheck(node: Node) -> None:
    """Keeps mypy aware that subtrees are nodes."""
    assert isinstance(node, Node)


def test_subtree_is_a_node() -> None:
    helper_typecheck(doubler_subtree())
    assert AlwaysSuccess is not None
