"""The nodes that run scripts: BehaviorTree.CPP's Script, ScriptCondition and Precondition.

Each holds its script as an option, parsed when the node is made (a syntax error is a
TreeError naming the column) and compiled when the tree's blackboard is given to it
(:meth:`ScriptNode.bind`, called by the XML loader): a tree file uses them through
BehaviorTree.CPP XML, whose blackboard they read and write. A script that fails while
running fails its node with the reason (BehaviorTree.CPP throws out of the tick).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

from btcap.bt.blackboard import Blackboard
from btcap.bt.decorators import Decorator
from btcap.bt.node import Leaf, Node
from btcap.bt.ports import Port
from btcap.bt.scripting.compiler import Compiled, compile_script
from btcap.bt.scripting.lexer import ScriptSyntaxError
from btcap.bt.scripting.parser import Script as Parsed
from btcap.bt.scripting.parser import parse
from btcap.bt.scripting.values import ScriptError, to_bool
from btcap.bt.state import State, TreeError

__all__ = [
    "CONDITIONS",
    "Script",
    "ScriptCondition",
    "ScriptConditions",
    "ScriptNode",
    "ScriptPrecondition",
    "bind_script",
]

_SUCCEEDED, _FAILED, _RUNNING, _ERROR = State.SUCCEEDED, State.FAILED, State.RUNNING, State.ERROR
_SKIPPED = State.SKIPPED
_ACTIVE = (State.RUNNING, State.ASSIGNED, State.UNASSIGNED)


class _EntryCell:
    """One blackboard entry as a script sees it (resolved through subtree remaps)."""

    __slots__ = ("board", "name", "type", "values")

    def __init__(self, board: Blackboard, key: str) -> None:
        self.board, self.name = board.owner(key)
        self.values: dict[str, Any] = self.board.outputs
        port = self.board.ports.get(self.name)
        self.type = Any if port is None else port.type

    def arrived(self) -> None:
        self.board._arrived(self.name)


def parsed(code: str, what: str) -> Parsed:
    """The parsed script, or a TreeError naming ``what`` and the column."""
    try:
        return parse(code)
    except ScriptSyntaxError as exc:
        raise TreeError(f"{what} {code!r}: {exc}") from None


def bind_script(script: Parsed, board: Blackboard, enums: Mapping[str, int]) -> Compiled:
    """The script compiled over ``board``'s entries (declared untyped if new)."""
    cells = {}
    for key in dict.fromkeys((*script.reads, *script.writes)):
        if key in enums:
            continue
        owner, name = board.owner(key)
        if name not in owner.ports:
            owner.declare(name, Port(Any))
        cells[key] = _EntryCell(board, key)
    return compile_script(script, cells, enums)


def _unbound() -> Any:
    raise ScriptError("the script has no blackboard (load the tree from BehaviorTree.CPP XML)")


class ScriptNode(Node):
    """A node running scripts given as options (:attr:`SCRIPTS` names them)."""

    __slots__ = ("_code", "_parsed", "_runs")
    SCRIPTS: ClassVar[tuple[str, ...]] = ("code",)

    def declare_ports(self) -> None:
        super().declare_ports()
        self._parsed = {
            k: parsed(self.options[k], f"{type(self).__name__} {k}") for k in self.script_options()
        }
        self._runs: dict[str, Compiled] = dict.fromkeys(self._parsed, _unbound)
        self._code: Compiled = _unbound  # the first script, called directly

    def script_options(self) -> tuple[str, ...]:
        """The options holding this node's scripts."""
        return self.SCRIPTS

    def bind(self, board: Blackboard, enums: Mapping[str, int]) -> None:
        """Compile the scripts over ``board`` (the tree's blackboard)."""
        self._runs = {k: bind_script(p, board, enums) for k, p in self._parsed.items()}
        self._code = next(iter(self._runs.values()), _unbound)

    def scripts(self) -> dict[str, Parsed]:
        return dict(self._parsed)


class Script(ScriptNode, Leaf):
    """Runs its script and succeeds (BehaviorTree.CPP's Script)."""

    __slots__ = ()
    OPTIONS: ClassVar[dict[str, Any]] = {"code": Port(str, description="the script")}

    def on_tick(self) -> State:
        self._code()
        return _SUCCEEDED


class ScriptCondition(ScriptNode, Leaf):
    """Succeeds if its script's value is true, else fails (BehaviorTree.CPP's ScriptCondition)."""

    __slots__ = ()
    OPTIONS: ClassVar[dict[str, Any]] = {"code": Port(str, description="the condition")}

    def on_tick(self) -> State:
        value = self._code()
        if value == 1.0 and type(value) is float:
            return _SUCCEEDED
        return _SUCCEEDED if to_bool(value, "the condition's value") else _FAILED


_ELSE = {"SUCCESS": _SUCCEEDED, "FAILURE": _FAILED, "RUNNING": _RUNNING, "SKIPPED": _SKIPPED}


class ScriptPrecondition(ScriptNode, Decorator):
    """Ticks its child if ``if`` is true, else gives ``else`` (BehaviorTree.CPP's
    Precondition): the condition is checked only until the child runs, and again once
    the child finished or was unticked."""

    __slots__ = ("_else", "_started")
    SCRIPTS = ("if",)
    OPTIONS: ClassVar[dict[str, Any]] = {
        "if": Port(str, description="the condition"),
        "else": Port(str, "FAILURE", description="SUCCESS, FAILURE, RUNNING or SKIPPED"),
    }

    def declare_ports(self) -> None:
        super().declare_ports()
        word = self.options["else"]
        if word not in _ELSE:
            raise TreeError(
                f"Precondition else={word!r}: expected SUCCESS, FAILURE, RUNNING or SKIPPED"
            )
        self._else = _ELSE[word]
        self._started = False

    def on_tick(self) -> State:
        if not self._started:
            if not to_bool(self._runs["if"](), "the condition's value"):
                return self._else
            self._started = True
        child = self.children[0]
        s = child.tick()
        if s is _SUCCEEDED or s is _FAILED:
            # Not reset: BehaviorTree.CPP only sets the child's status back to IDLE, so a
            # SequenceWithMemory below keeps its place after a failure.
            self._started = False
            return s
        if s is _ERROR:  # a failure, the child keeps its error for whoever looks
            self._started = False
            return _FAILED
        return s

    def on_untick(self) -> None:
        super().on_untick()
        self._started = False

    def on_reset(self) -> None:
        self._started = False


#: BehaviorTree.CPP's pre/post-condition attributes and the options of ScriptConditions.
CONDITIONS = {
    "_failureIf": "failure_if",
    "_successIf": "success_if",
    "_skipIf": "skip_if",
    "_while": "while_true",
    "_onSuccess": "on_success",
    "_onFailure": "on_failure",
    "_post": "post",
    "_onHalted": "on_halted",
}


class ScriptConditions(ScriptNode, Decorator):
    """BehaviorTree.CPP's pre/post conditions of one node, as a decorator around it.

    Before a tick that starts the node (it is not running): ``failure_if``, then
    ``success_if``, then ``skip_if``, if true, give FAILED, SUCCEEDED or SKIPPED without
    ticking it, and ``while_true``, if false, gives SKIPPED. While the node runs,
    ``while_true`` turning false halts it (``on_halted`` runs) and gives SKIPPED. When the
    node (or a pre-condition) gives a result, not SKIPPED: ``on_success`` or
    ``on_failure``, then ``post``. ``on_halted`` runs when the running node is unticked.
    Empty options do nothing.
    """

    __slots__ = ("_post", "_pre", "_while")
    OPTIONS: ClassVar[dict[str, Any]] = {
        name: Port(str, "", description=f"BehaviorTree.CPP's {attr}")
        for attr, name in CONDITIONS.items()
    }

    def script_options(self) -> tuple[str, ...]:
        return tuple(k for k in CONDITIONS.values() if self.options[k])

    def declare_ports(self) -> None:
        super().declare_ports()
        self._arrange()

    def bind(self, board: Blackboard, enums: Mapping[str, int]) -> None:
        super().bind(board, enums)
        self._arrange()

    def _arrange(self) -> None:
        """The scripts in the order BehaviorTree.CPP runs them."""
        runs = self._runs
        pre = (
            ("failure_if", _FAILED, True),
            ("success_if", _SUCCEEDED, True),
            ("skip_if", _SKIPPED, True),
            ("while_true", _SKIPPED, False),
        )
        self._pre = [(runs[k], r, when) for k, r, when in pre if k in runs]
        self._while = runs.get("while_true")
        self._post = {
            s: [runs[k] for k in (first, "post") if k in runs]
            for s, first in ((_SUCCEEDED, "on_success"), (_FAILED, "on_failure"))
        }

    def on_tick(self) -> State:
        child = self.children[0]
        if self.state not in _ACTIVE:
            for run, result, when in self._pre:
                if to_bool(run(), "the pre-condition's value") is when:
                    return _SKIPPED if result is _SKIPPED else self._finished(result)
        elif self._while is not None and not to_bool(self._while(), "the _while value"):
            if child.state in _ACTIVE:  # halted as BehaviorTree.CPP halts: to start afresh
                child.untick()
            child.reset()
            if "on_halted" in self._runs:
                self._runs["on_halted"]()
            return _SKIPPED
        s = child.tick()
        if s is _SUCCEEDED or s is _FAILED:
            return self._finished(s)
        if s is _ERROR:  # as BehaviorTree.CPP's exception: no post-condition runs
            raise ScriptError(f"node {child.path!r} failed: {child.error}")
        return s

    def _finished(self, result: State) -> State:
        for run in self._post[result]:
            run()
        return result

    def on_untick(self) -> None:
        running = self.children[0].state in _ACTIVE
        super().on_untick()
        if running and "on_halted" in self._runs:
            self._runs["on_halted"]()
