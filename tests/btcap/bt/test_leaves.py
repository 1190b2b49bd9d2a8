"""Ready-made leaves: Action, Condition, Constant, Wait, Log, Compare, and a custom leaf."""

from __future__ import annotations

import asyncio
from typing import Any

import anyio
import msgspec
import pytest
from structlog.testing import capture_logs

from btcap import (
    Action,
    AlwaysFailure,
    AlwaysRunning,
    AlwaysSuccess,
    Compare,
    Condition,
    Constant,
    Leaf,
    Log,
    Port,
    ReactiveSequence,
    Sequence,
    State,
    Tree,
    TreeError,
    Wait,
)
from btcap.actors import ManualClock

S, F, R = State.SUCCEEDED, State.FAILED, State.RUNNING


async def settle() -> None:
    """Let background tasks run until they block."""
    for _ in range(5):
        await asyncio.sleep(0)


class Gate:
    """An async callable that runs until released, recording what happened to it."""

    def __init__(self, result: Any = None) -> None:
        self.result = result
        self.release = asyncio.Event()
        self.calls: list[dict[str, Any]] = []
        self.cancelled = 0
        self.finished = 0

    async def __call__(self, **inputs: Any) -> Any:
        self.calls.append(inputs)
        try:
            await self.release.wait()
        except asyncio.CancelledError:
            self.cancelled += 1
            raise
        self.finished += 1
        if isinstance(self.result, BaseException):
            raise self.result
        return self.result


def no_tasks_left() -> bool:
    return not (asyncio.all_tasks() - {asyncio.current_task()})


# -- Action -------------------------------------------------------------------------------


async def test_action_runs_in_the_background_until_done() -> None:
    with anyio.fail_after(5):
        gate = Gate()
        tree = Tree(Action(gate, "work"))
        assert tree.tick() is R  # the first tick starts it
        assert gate.calls == []  # ... but never runs it inside the tick
        await settle()
        assert gate.calls == [{}]
        assert tree.tick() is R
        assert tree.tick() is R
        gate.release.set()
        await settle()
        assert tree.tick() is S
        assert gate.calls == [{}]  # one run, however many ticks
        await tree.shutdown()


@pytest.mark.parametrize(
    ("result", "expected"),
    [(None, S), (True, S), (False, F), (42, S), ("ok", S), ({}, S)],
)
async def test_action_result_mapping(result: Any, expected: State) -> None:
    with anyio.fail_after(5):
        gate = Gate(result)
        gate.release.set()
        tree = Tree(Action(gate, "work"))
        tree.tick()
        await settle()
        assert tree.tick() is expected
        await tree.shutdown()


async def test_action_dict_result_fills_outputs() -> None:
    with anyio.fail_after(5):
        gate = Gate({"pose": [1, 2], "found": True})
        gate.release.set()
        act = Action(gate, "look", outputs={"pose": tuple[float, float], "found": bool})
        tree = Tree(act)
        tree.tick()
        await settle()
        assert tree.tick() is S
        assert act.outputs == {"pose": (1.0, 2.0), "found": True}
        await tree.shutdown()


@pytest.mark.parametrize(
    ("result", "message"),
    [
        ({"nope": 1}, "returned unknown output 'nope'"),
        ({"count": "many"}, "output 'count': expected int, got str"),
    ],
)
async def test_action_bad_dict_result_is_an_error(result: dict[str, Any], message: str) -> None:
    with anyio.fail_after(5):
        gate = Gate(result)
        gate.release.set()
        act = Action(gate, "count", outputs={"count": int})
        tree = Tree(act)
        tree.tick()
        await settle()
        with capture_logs():
            assert tree.tick() is State.ERROR
        assert isinstance(act.error, TreeError)
        assert message in str(act.error)
        await tree.shutdown()


async def test_action_exception_is_an_error() -> None:
    with anyio.fail_after(5):
        gate = Gate(ValueError("arm jammed"))
        gate.release.set()
        act = Action(gate, "grip")
        tree = Tree(act)
        tree.tick()
        await settle()
        with capture_logs() as logs:
            assert tree.tick() is State.ERROR
        assert isinstance(act.error, ValueError)
        assert str(act.error) == "arm jammed"
        assert logs[0]["node"] == "grip"
        assert tree.errors() == [act]
        await tree.shutdown()


async def test_action_gets_its_inputs_as_keywords_from_the_starting_tick() -> None:
    with anyio.fail_after(5):
        gate = Gate()
        act = Action(gate, "go", inputs={"x": float, "label": Port(str, "none")})
        act.set_input("x", 1)
        tree = Tree(act)
        tree.tick()
        act.set_input("x", 2.0)  # changed before the task got to run
        await settle()
        assert gate.calls == [{"x": 1.0, "label": "none"}]
        await tree.shutdown()


async def test_action_input_from_a_wire() -> None:
    with anyio.fail_after(5):
        gate = Gate()
        act = Action(gate, "go", inputs={"target": str})
        tree = Tree(
            ReactiveSequence("root", children=[Constant("where", value="dock", type=str), act])
        )
        tree.wire("root/where", "value", "root/go", "target")
        tree.tick()
        await settle()
        assert gate.calls == [{"target": "dock"}]
        await tree.shutdown()


@pytest.mark.parametrize("action", ["untick", "reset", "shutdown"])
async def test_action_is_cancelled_on_untick_reset_and_shutdown(action: str) -> None:
    with anyio.fail_after(5):
        gate = Gate()
        act = Action(gate, "work")
        tree = Tree(act)
        tree.tick()
        await settle()
        if action == "shutdown":
            await tree.shutdown()
        else:
            getattr(tree, action)()
            await settle()
        assert gate.cancelled == 1
        assert gate.finished == 0
        assert act.state is {"untick": State.PAUSED, "reset": State.IDLE}.get(
            action, State.SHUTDOWN
        )
        assert no_tasks_left()
        await tree.shutdown()


async def test_paused_action_starts_afresh() -> None:
    with anyio.fail_after(5):
        gate = Gate()
        tree = Tree(Action(gate, "work"))
        tree.tick()
        await settle()
        tree.untick()
        assert tree.tick() is R
        await settle()
        assert len(gate.calls) == 2
        gate.release.set()
        await settle()
        assert tree.tick() is S
        await tree.shutdown()


async def test_finished_action_runs_again_on_the_next_tick() -> None:
    with anyio.fail_after(5):
        gate = Gate()
        gate.release.set()
        tree = Tree(Action(gate, "work"))
        tree.tick()
        await settle()
        assert tree.tick() is S
        assert tree.tick() is R
        await settle()
        assert tree.tick() is S
        assert len(gate.calls) == 2
        await tree.shutdown()


async def test_action_cancelled_from_outside_fails() -> None:
    with anyio.fail_after(5):
        gate = Gate()
        tree = Tree(Action(gate, "work"))
        tree.tick()
        await settle()
        for task in asyncio.all_tasks() - {asyncio.current_task()}:
            task.cancel()
        await settle()
        assert tree.tick() is F
        await tree.shutdown()


def test_action_ticked_without_an_event_loop_is_an_error_and_leaks_nothing() -> None:
    act = Action(Gate(), "work")
    tree = Tree(act)
    with capture_logs():
        assert tree.tick() is State.ERROR
    assert isinstance(act.error, TreeError)
    assert "running event loop" in str(act.error)


def test_action_names_itself_after_its_function() -> None:
    async def drive_home() -> None:
        pass

    assert Action(drive_home).name == "drive_home"
    assert Action(drive_home, "other").name == "other"


# -- Condition ------------------------------------------------------------------------


def test_condition_with_inputs() -> None:
    def charged(level: float, minimum: float) -> bool:
        return level >= minimum

    cond = Condition(charged, inputs={"level": float, "minimum": Port(float, 0.5)})
    assert cond.name == "charged"
    cond.set_input("level", 0.7)
    tree = Tree(cond)
    assert tree.tick() is S
    cond.set_input("minimum", 0.9)
    assert tree.tick() is F
    with pytest.raises(TreeError, match="expected float"):
        cond.set_input("level", "full")


def test_condition_without_inputs_and_required_input_validation() -> None:
    flag = {"up": False}
    tree = Tree(Condition(lambda: flag["up"], "is_up"))
    assert tree.tick() is F
    flag["up"] = True
    assert tree.tick() is S
    needy = Tree(Condition(lambda x: x, "needy", inputs={"x": bool}))
    with pytest.raises(TreeError, match="input 'x' needs a value or a wire"):
        needy.tick()


def test_condition_predicate_raising_is_an_error() -> None:
    def broken() -> bool:
        return 1 / 0 > 0

    tree = Tree(Condition(broken, "div"))
    with capture_logs():
        assert tree.tick() is State.ERROR
    assert isinstance(tree.root.error, ZeroDivisionError)


# -- Constant -------------------------------------------------------------------------


def test_constant_outputs_its_value_with_its_type() -> None:
    k = Constant("k", value=[1, 2], type=tuple[int, int])
    assert k.output_ports["value"].type == tuple[int, int]
    assert k.outputs == {"value": None}
    assert Tree(k).tick() is S
    assert k.outputs == {"value": (1, 2)}


def test_constant_value_must_match_its_type() -> None:
    with pytest.raises(TreeError, match="node 'k' option 'value': expected int, got str"):
        Constant("k", value="three", type=int)
    with pytest.raises(TreeError, match=r"option 'value' \(Any\) is required"):
        Constant("k")
    assert Constant("k", value=None).options["value"] is None


def test_constant_outputs_are_cleared_by_reset() -> None:
    k = Constant("k", value=3)
    tree = Tree(k)
    tree.tick()
    tree.reset()
    assert k.outputs == {"value": None}


# -- Wait -----------------------------------------------------------------------------


async def test_wait_runs_for_clock_seconds() -> None:
    with anyio.fail_after(5):
        clock = ManualClock(start=100.0)
        tree = Tree(Wait("wait", seconds=2), clock=clock)
        assert tree.tick() is R
        await clock.advance(1.99)
        assert tree.tick() is R
        await clock.advance(0.01)
        assert tree.tick() is S
        assert tree.tick() is R  # starts over
        await clock.advance(2)
        assert tree.tick() is S


async def test_wait_survives_untick_and_restarts_on_reset() -> None:
    with anyio.fail_after(5):
        clock = ManualClock()
        tree = Tree(Wait("wait", seconds=2), clock=clock)
        tree.tick()
        await clock.advance(1)
        tree.untick()
        await clock.advance(1)
        assert tree.tick() is S  # the deadline is kept while paused
        tree.tick()
        await clock.advance(1)
        tree.reset()
        assert tree.tick() is R
        await clock.advance(1.5)
        assert tree.tick() is R


def test_wait_needs_seconds_and_refuses_negative_ones() -> None:
    with pytest.raises(TreeError, match=r"option 'seconds' \(float\) is required"):
        Wait("wait")
    with pytest.raises(TreeError) as err:
        Wait("w", seconds=-5)
    assert str(err.value) == "node 'w' option 'seconds': must be >= 0, got -5"
    assert Tree(Wait("w", seconds=0)).tick() is S


class Pace(Leaf):
    """A leaf of one's own whose input is a duration: a wired value is checked per tick."""

    INPUTS = {"period": Port(float, 1.0, "seconds", msgspec.Meta(ge=0))}

    def on_tick(self) -> State:
        return S


def test_a_constrained_input_refuses_a_bad_constant_and_errs_on_a_bad_wired_value() -> None:
    with pytest.raises(TreeError, match="node 'p' input 'period': must be >= 0, got -1"):
        Pace("p", inputs={"period": -1})
    source = Constant("src", value=-2.0, type=float)
    pace = Pace("p")
    tree = Tree(Sequence("root", children=[source, pace]))
    tree.wire("root/src", "value", "root/p", "period")
    with capture_logs() as logs:
        assert tree.tick() is F
    assert pace.state is State.ERROR
    assert str(pace.error) == "node 'root/p' input 'period': must be >= 0, got -2.0"
    assert [e["node"] for e in logs if e["event"] == "btcap.node_error"] == ["root/p"]
    tree.reset()
    source.options["value"] = 3  # converted like a constant: int to float
    assert tree.tick() is S
    assert pace.inputs["period"] == 3.0


# -- Log ------------------------------------------------------------------------------


@pytest.mark.parametrize("level", ["debug", "info", "warning", "error"])
def test_log_emits_the_message_with_the_value(level: str) -> None:
    log = Log("say", message="battery level", level=level)
    tree = Tree(ReactiveSequence("root", children=[Constant("lvl", value=0.3, type=float), log]))
    tree.wire("root/lvl", "value", "root/say", "value")
    with capture_logs() as logs:
        assert tree.tick() is S
    assert logs == [
        {"event": "battery level", "node": "root/say", "value": 0.3, "log_level": level}
    ]


def test_log_defaults_and_bad_level() -> None:
    with capture_logs() as logs:
        assert Tree(Log("say", message="hi")).tick() is S
    assert logs == [{"event": "hi", "node": "say", "value": None, "log_level": "info"}]
    with pytest.raises(TreeError, match="level must be debug, info, warning or error"):
        Log("say", message="hi", level="loud")
    with pytest.raises(TreeError, match="option 'message'"):
        Log("say")


# -- Compare ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("op", "a", "b", "expected"),
    [
        ("==", 1, 1, S),
        ("==", 1, 2, F),
        ("!=", 1, 2, S),
        ("!=", "x", "x", F),
        ("<", 1, 2, S),
        ("<", 2, 2, F),
        ("<=", 2, 2, S),
        ("<=", 3, 2, F),
        (">", 3, 2, S),
        (">", 2, 2, F),
        (">=", 2, 2, S),
        (">=", 1.5, 2, F),
    ],
)
def test_compare_ops(op: str, a: Any, b: Any, expected: State) -> None:
    cmp = Compare("cmp", op=op, inputs={"a": a, "b": b})
    assert Tree(cmp).tick() is expected


def test_compare_default_op_is_equality() -> None:
    cmp = Compare("cmp", inputs={"a": None, "b": None})
    assert Tree(cmp).tick() is S


@pytest.mark.parametrize("op", ["=", "<>", "is", ""])
def test_compare_rejects_bad_ops(op: str) -> None:
    with pytest.raises(TreeError, match=f"op {op!r}; expected one of ==, !=, <, <=, >, >="):
        Compare("cmp", op=op)


def test_compare_of_incomparable_values_is_an_error() -> None:
    cmp = Compare("cmp", op="<", inputs={"a": 1, "b": "x"})
    with capture_logs():
        assert Tree(cmp).tick() is State.ERROR
    assert isinstance(cmp.error, TypeError)


def test_always_leaves() -> None:
    assert Tree(AlwaysSuccess()).tick() is S
    assert Tree(AlwaysFailure()).tick() is F
    assert Tree(AlwaysRunning()).tick() is R


# -- a custom leaf, as in the leaves module docstring ---------------------------------


class Battery(Leaf):
    """Succeeds while the battery holds enough charge."""

    INPUTS = {"level": float}
    OPTIONS = {"minimum": Port(float, 0.2)}

    def on_tick(self) -> State:
        ok = self.inputs["level"] >= self.options["minimum"]
        return State.SUCCEEDED if ok else State.FAILED


def test_custom_leaf_in_ten_lines() -> None:
    low = Battery("low", inputs={"level": 0.1})
    picky = Battery("picky", minimum=0.5, inputs={"level": 0.4})
    assert Tree(low).tick() is F
    assert Tree(picky).tick() is F
    picky.set_input("level", 0.6)
    assert picky.tick() is S
    assert {"level": Port(float)} == Battery.INPUTS
    with pytest.raises(TreeError, match="input 'level' needs a value or a wire"):
        Tree(Battery("unwired")).tick()
    with pytest.raises(TreeError, match="option 'minimum': expected float"):
        Battery(minimum="high")
