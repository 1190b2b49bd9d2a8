"""The node life cycle: setup, tick, untick, reset, shutdown, errors, structure, messages."""

from __future__ import annotations

from typing import Any, TypeVar

import pytest
from structlog.testing import capture_logs

from btcap import (
    AlwaysSuccess,
    IllegalTransition,
    Inverter,
    Leaf,
    Node,
    Parallel,
    ReactiveFallback,
    ReactiveSequence,
    State,
    Tree,
    TreeError,
)
from btcap.bt.messages import (
    NODE_MESSAGES,
    NodeStatus,
    Reset,
    Setup,
    Shutdown,
    Tick,
    Untick,
)
from btcap.team.runtime.protocol import protocol_registry
from btcap.transports import Address, Codec, Envelope, Kind, Message


class Fixed(Leaf):
    """Returns ``result`` (settable) and counts its ticks."""

    def __init__(self, name: str = "fixed", result: State = State.SUCCEEDED) -> None:
        super().__init__(name)
        self.result = result
        self.ticks = 0

    def on_tick(self) -> State:
        self.ticks += 1
        return self.result


class Hooks(Leaf):
    """Records every hook into a shared journal and can be told to raise in one of them."""

    OUTPUTS = {"out": int}

    def __init__(self, name: str, journal: list[str], fail_in: str = "") -> None:
        super().__init__(name)
        self.journal = journal
        self.fail_in = fail_in
        self.result = State.RUNNING

    def _hook(self, what: str) -> None:
        self.journal.append(f"{self.name}.{what}")
        if what == self.fail_in:
            raise RuntimeError(f"{self.name} broke in {what}")

    def on_setup(self) -> None:
        self._hook("setup")

    def on_tick(self) -> State:
        self._hook("tick")
        self.outputs["out"] = 7
        return self.result

    def on_untick(self) -> None:
        self._hook("untick")

    def on_reset(self) -> None:
        self._hook("reset")

    def on_shutdown(self) -> None:
        self._hook("shutdown")


class Returns(Leaf):
    """Returns whatever it was given, State or not."""

    def __init__(self, value: Any) -> None:
        super().__init__("returns")
        self.value = value

    def on_tick(self) -> Any:
        return self.value


N = TypeVar("N", bound=Node)


def ready(node: N) -> N:
    node.setup()
    return node


def state_of(node: Node) -> State:
    """A node's state, read afresh (mypy would keep an earlier narrowing)."""
    return node.state


# -- life cycle -----------------------------------------------------------------------


def test_new_node_is_uninitialized_with_no_error() -> None:
    n = Fixed()
    assert n.state is State.UNINITIALIZED
    assert n.error is None
    assert n.name == "fixed"
    assert AlwaysSuccess().name == "AlwaysSuccess"


@pytest.mark.parametrize("action", ["tick", "untick", "reset"])
def test_actions_before_setup_raise_a_clear_illegal_transition(action: str) -> None:
    root = ReactiveSequence("root", children=[Fixed("leaf")])
    Tree(root)
    leaf = root.children[0]
    with pytest.raises(IllegalTransition, match=rf"{action} of 'root/leaf' while uninitialized"):
        getattr(leaf, action)()
    with pytest.raises(IllegalTransition, match="call setup\\(\\) first"):
        getattr(leaf, action)()
    assert leaf.state is State.UNINITIALIZED


def test_illegal_transition_is_a_tree_error() -> None:
    assert issubclass(IllegalTransition, TreeError)


@pytest.mark.parametrize("action", ["tick", "untick", "reset"])
def test_actions_after_shutdown_raise(action: str) -> None:
    n = ready(Fixed())
    n.shutdown()
    with pytest.raises(IllegalTransition, match="while shutdown"):
        getattr(n, action)()


def test_setup_goes_idle_children_first() -> None:
    journal: list[str] = []
    root = ReactiveSequence("root", children=[Hooks("a", journal), Hooks("b", journal)])
    root.setup()
    assert journal == ["a.setup", "b.setup"]
    assert [n.state for n in root.walk()] == [State.IDLE] * 3


@pytest.mark.parametrize("result", [State.SUCCEEDED, State.FAILED, State.RUNNING])
def test_setup_only_from_uninitialized_or_shutdown(result: State) -> None:
    n = ready(Fixed(result=result))
    with pytest.raises(IllegalTransition, match="expected uninitialized or shutdown"):
        n.setup()
    n.tick()
    with pytest.raises(IllegalTransition, match=f"setup of 'fixed' while {result.value}"):
        n.setup()
    n.shutdown()
    n.setup()
    assert n.state is State.IDLE


def test_tick_returns_and_stores_the_new_state() -> None:
    n = ready(Fixed(result=State.FAILED))
    assert n.tick() is State.FAILED
    assert n.state is State.FAILED
    n.result = State.SUCCEEDED
    assert n.tick() is State.SUCCEEDED
    assert n.ticks == 2


@pytest.mark.parametrize(
    ("before", "after"),
    [
        (State.RUNNING, State.PAUSED),
        (State.ASSIGNED, State.PAUSED),
        (State.UNASSIGNED, State.PAUSED),
        (State.PAUSED, State.PAUSED),
        (State.SUCCEEDED, State.IDLE),
        (State.FAILED, State.IDLE),
    ],
)
def test_untick_pauses_active_nodes_and_idles_the_rest(before: State, after: State) -> None:
    n = ready(Fixed(result=before))
    n.tick()
    assert n.state is before
    n.untick()
    assert n.state is after


def test_untick_of_idle_node_stays_idle_and_calls_the_hook() -> None:
    journal: list[str] = []
    n = ready(Hooks("h", journal))
    n.untick()
    assert n.state is State.IDLE
    assert journal == ["h.setup", "h.untick"]


def test_untick_of_a_composite_unticks_only_active_children() -> None:
    journal: list[str] = []
    done = Hooks("done", journal)
    done.result = State.SUCCEEDED
    busy = Hooks("busy", journal)
    root = ready(Parallel("root", children=[done, busy]))
    assert root.tick() is State.RUNNING
    journal.clear()
    root.untick()
    assert journal == ["busy.untick"]
    assert (root.state, done.state, busy.state) == (State.PAUSED, State.SUCCEEDED, State.PAUSED)


def test_reset_goes_idle_clears_outputs_and_error_and_resets_children() -> None:
    journal: list[str] = []
    a, b = Hooks("a", journal), Hooks("b", journal, fail_in="tick")
    root = ready(Parallel("root", children=[a, b]))
    with capture_logs():
        root.tick()
    assert a.outputs == {"out": 7}
    assert b.state is State.ERROR
    assert b.error is not None
    journal.clear()
    root.reset()
    assert journal == ["a.reset", "b.reset"]
    assert [n.state for n in root.walk()] == [State.IDLE] * 3
    assert a.outputs == {"out": None}
    assert b.error is None


def test_reset_from_paused_goes_idle() -> None:
    n = ready(Fixed(result=State.RUNNING))
    n.tick()
    n.untick()
    n.reset()
    assert n.state is State.IDLE


def test_shutdown_then_setup_again() -> None:
    journal: list[str] = []
    root = ReactiveSequence("root", children=[Hooks("a", journal)])
    root.setup()
    root.tick()
    root.shutdown()
    assert [n.state for n in root.walk()] == [State.SHUTDOWN] * 2
    assert journal == ["a.setup", "a.tick", "a.shutdown"]
    root.setup()
    assert [n.state for n in root.walk()] == [State.IDLE] * 2
    assert root.tick() is State.RUNNING


def test_shutdown_of_uninitialized_or_shutdown_node_does_nothing() -> None:
    journal: list[str] = []
    n = Hooks("h", journal)
    n.shutdown()
    assert n.state is State.UNINITIALIZED
    n.setup()
    n.shutdown()
    n.shutdown()
    assert state_of(n) is State.SHUTDOWN
    assert journal == ["h.setup", "h.shutdown"]


# -- errors -----------------------------------------------------------------------------


def test_exception_in_on_tick_is_an_error_state_logged_and_not_raised() -> None:
    journal: list[str] = []
    bad = Hooks("bad", journal, fail_in="tick")
    tree = Tree(ReactiveSequence("root", children=[bad]))
    with capture_logs() as logs:
        assert tree.tick() is State.FAILED
    assert bad.state is State.ERROR
    assert isinstance(bad.error, RuntimeError)
    assert str(bad.error) == "bad broke in tick"
    assert tree.errors() == [bad]
    [entry] = [e for e in logs if e["event"] == "btcap.node_error"]
    assert entry["node"] == "root/bad"
    assert entry["action"] == "tick"
    assert entry["log_level"] == "error"
    assert entry["exc_info"] is bad.error


def test_exception_in_the_root_does_not_escape_tree_tick() -> None:
    tree = Tree(Hooks("bad", [], fail_in="tick"))
    with capture_logs():
        assert tree.tick() is State.ERROR
        assert tree.tick() is State.ERROR
    assert tree.root.state is State.ERROR


@pytest.mark.parametrize("value", [None, "succeeded", 1, True])
def test_on_tick_returning_a_non_state_is_an_error(value: Any) -> None:
    n = ready(Returns(value))
    with capture_logs():
        assert n.tick() is State.ERROR
    assert isinstance(n.error, TypeError)
    assert "expected a State" in str(n.error)


def test_error_recovers_on_the_next_good_tick() -> None:
    n = ready(Hooks("h", [], fail_in="tick"))
    with capture_logs():
        n.tick()
    assert n.state is State.ERROR
    n.fail_in = ""
    assert n.tick() is State.RUNNING


@pytest.mark.parametrize("hook", ["untick", "reset"])
def test_exception_in_untick_or_reset_is_an_error(hook: str) -> None:
    n = ready(Hooks("h", [], fail_in=hook))
    n.tick()
    with capture_logs() as logs:
        getattr(n, hook)()
    assert n.state is State.ERROR
    assert isinstance(n.error, RuntimeError)
    assert logs[0]["action"] == hook


def test_exception_in_on_shutdown_is_logged_and_the_node_still_shuts_down() -> None:
    n = ready(Hooks("h", [], fail_in="shutdown"))
    with capture_logs() as logs:
        n.shutdown()
    assert n.state is State.SHUTDOWN
    assert logs[0]["event"] == "btcap.node_shutdown_failed"


def test_exception_in_on_setup_is_an_error_of_that_node() -> None:
    n = Hooks("h", [], fail_in="setup")
    with capture_logs():
        n.setup()
    assert n.state is State.ERROR
    assert isinstance(n.error, RuntimeError)


def test_tree_setup_failure_raises_naming_the_node_and_can_be_retried() -> None:
    bad = Hooks("bad", [], fail_in="setup")
    tree = Tree(ReactiveSequence("root", children=[bad, Fixed("ok")]))
    with capture_logs(), pytest.raises(TreeError, match="setup failed: root/bad: RuntimeError"):
        tree.tick()
    assert {n.state for n in tree.nodes()} == {State.SHUTDOWN}
    bad.fail_in = ""
    assert tree.tick() is State.RUNNING


# -- structure ------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["", "a/b", "a.b"])
def test_bad_node_names_are_rejected(name: str) -> None:
    with pytest.raises(TreeError, match="node name"):
        Fixed(name)


def test_path_and_walk() -> None:
    c = Fixed("c")
    root = ReactiveSequence(
        "root", children=[ReactiveFallback("f", children=[Fixed("a"), c]), Fixed("b")]
    )
    assert c.path == "root/f/c"
    assert root.path == "root"
    assert [n.name for n in root.walk()] == ["root", "f", "a", "c", "b"]
    assert c.parent_node is root.children[0]


def test_add_child_checks() -> None:
    with pytest.raises(TreeError, match="at most 1 children"):
        Inverter("inv", children=[Fixed("a"), Fixed("b")])
    with pytest.raises(TreeError, match="at most 0 children"):
        Fixed("leaf").add_child(Fixed("x"))
    with pytest.raises(TreeError, match="already has a child named 'a'"):
        ReactiveSequence("s", children=[Fixed("a"), Fixed("a")])
    a = Fixed("a")
    ReactiveSequence("s1", children=[a])
    with pytest.raises(TreeError, match="already has parent 's1'"):
        ReactiveSequence("s2", children=[a])


def test_add_child_at_index_and_remove_child() -> None:
    root = ReactiveSequence("root", children=[Fixed("a"), Fixed("c")])
    b = root.add_child(Fixed("b"), 1)
    assert [c.name for c in root.children] == ["a", "b", "c"]
    root.remove_child(b)
    assert b.parent_node is None
    assert [c.name for c in root.children] == ["a", "c"]
    with pytest.raises(TreeError, match="not a child"):
        root.remove_child(b)


def test_cannot_add_or_remove_children_of_active_nodes() -> None:
    busy = Fixed("busy", State.RUNNING)
    root = ready(ReactiveSequence("root", children=[busy]))
    root.tick()
    with pytest.raises(IllegalTransition, match="cannot add a child to 'root' while it is running"):
        root.add_child(Fixed("x"))
    with pytest.raises(IllegalTransition, match="cannot remove 'busy' while it is running"):
        root.remove_child(busy)


def test_node_outside_a_tree_has_no_tree_or_clock() -> None:
    n = Fixed()
    with pytest.raises(TreeError, match="not part of a Tree"):
        _ = n.tree
    with pytest.raises(TreeError, match="not part of a Tree"):
        _ = n.clock


def test_start_background_without_a_tree_raises_and_closes_the_coroutine() -> None:
    ran: list[bool] = []

    async def work() -> None:
        ran.append(True)

    with pytest.raises(TreeError, match="needs a Tree"):
        Fixed().start_background(work())
    assert ran == []  # and no "never awaited" warning (warnings are errors here)


def test_status_and_repr() -> None:
    n = ready(Hooks("h", []))
    n.tick()
    assert n.status() == NodeStatus(State.RUNNING, {"out": 7})
    assert repr(n) == "<Hooks 'h' running>"


# -- messages -----------------------------------------------------------------------------


SAMPLES: list[Message] = [
    Setup(),
    Tick(),
    Tick({"x": 1, "pose": [1.0, 2.0], "name": "a", "nested": {"k": None}}),
    Untick(),
    Reset(),
    Shutdown(),
    NodeStatus(State.RUNNING),
    NodeStatus(State.SUCCEEDED, {"value": 3.5, "items": [1, 2], "none": None}),
    *(NodeStatus(s) for s in State),
]


def test_every_node_message_has_a_sample() -> None:
    assert {type(m) for m in SAMPLES} == set(NODE_MESSAGES)


@pytest.mark.parametrize("msg", SAMPLES, ids=repr)
def test_node_messages_round_trip_through_the_codec(msg: Message) -> None:
    codec = Codec(protocol_registry())
    env = Envelope(Kind.ASK, Address("a", "tree:t"), Address("b", "tree:t/x"), msg, 5)
    back = codec.decode(codec.encode(env))
    assert back.msg == msg
    assert type(back.msg) is type(msg)
    assert codec.decode_message(codec.encode_message(msg)) == msg


def test_registry_holds_every_node_message() -> None:
    reg = protocol_registry()
    for t in NODE_MESSAGES:
        assert t in reg
