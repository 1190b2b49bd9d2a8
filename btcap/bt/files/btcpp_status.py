"""BehaviorTree.CPP 4's node statuses, followed through a btcap run, change by change.

BehaviorTree.CPP keeps a status per node that changes at more moments than btcap's
states do: a control node or decorator turns RUNNING when its tick starts, and it resets
its children to IDLE when it gives a result (halting the running ones first, depth
first); a reactive one resets all but the running child; a decorator resets its child
whenever the child gives a result; the tree resets its root after a result. Groot2
replays those changes. :class:`StatusFollower` is told which node btcap ticks and what
it returns, and applies BehaviorTree.CPP 4.8's rules for that node type to a status per
node, emitting ``(uid, status)`` on every change, in BehaviorTree.CPP's order. btcap's
own unticks and resets inside a tick are not needed: the rules say where
BehaviorTree.CPP halts. tests/btcap/bt/files/test_btlog.py checks the changes against
BehaviorTree.CPP's own FileLogger on the same trees and ticks.
"""

from __future__ import annotations

from collections.abc import Callable

from btcap.bt.files.btcpp_write import UidNode, btcpp_tag
from btcap.bt.state import State
from btcap.bt.tree import Subtree

__all__ = ["FAILURE", "IDLE", "RUNNING", "SKIPPED", "SUCCESS", "StatusFollower", "btcpp_status"]

#: BehaviorTree.CPP's NodeStatus codes, as the file logger writes them.
IDLE, RUNNING, SUCCESS, FAILURE, SKIPPED = 0, 1, 2, 3, 4

_STATUS = {
    State.SUCCEEDED: SUCCESS,
    State.FAILED: FAILURE,
    State.ERROR: FAILURE,  # BehaviorTree.CPP throws; the node failed
    State.IDLE: IDLE,
}

#: Control nodes whose tick halts every child but the running one (BehaviorTree.CPP 4.8).
_REACTIVE = frozenset({"ReactiveSequence", "ReactiveFallback"})


def btcpp_status(state: State) -> int:
    """A btcap state as BehaviorTree.CPP's status: waiting and paused ones are RUNNING."""
    return _STATUS.get(state, RUNNING)


class StatusFollower:
    """BehaviorTree.CPP's status of every node of one tree, moved by btcap's ticks.

    ``emit(uid, status)`` is called on every change. Call :meth:`enter` when a node's
    tick starts, :meth:`leave` with its result, :meth:`root_done` after a root tick, and
    :meth:`halt_tree` when the tree is halted from outside.
    """

    __slots__ = (
        "_children",
        "_deco",
        "_done_once",
        "_emit",
        "_kind",
        "_last",
        "_stack",
        "_status",
    )

    def __init__(self, nodes: list[UidNode], emit: Callable[[int, int], None]) -> None:
        self._emit = emit
        #: Per node uid: its status, its children's uids, its BehaviorTree.CPP kind.
        self._status = [IDLE] * (len(nodes) + 1)
        self._children: list[tuple[int, ...]] = [()] * (len(nodes) + 1)
        self._kind = [""] * (len(nodes) + 1)
        self._last = [-1] * (len(nodes) + 1)  # index of the child ticked last in this tick
        self._deco = [False] * (len(nodes) + 1)  # a decorator or SubTree: one child
        uids = {id(n): uid for uid, n, _ in nodes}
        for uid, n, _ in nodes:
            kids = [n.inner.root] if isinstance(n, Subtree) else n.children
            self._children[uid] = tuple(uids[id(c)] for c in kids)
            self._kind[uid] = btcpp_tag(n) if kids else ""
            self._deco[uid] = isinstance(n, Subtree) or type(n).MAX_CHILDREN == 1
        self._done_once: set[int] = set()  # RunOnce nodes whose child gave its result
        self._stack: list[int] = []

    def _set(self, uid: int, status: int) -> None:
        if self._status[uid] != status:
            self._status[uid] = status
            self._emit(uid, status)

    # -- BehaviorTree.CPP's halts and resets ----------------------------------------------
    def _reset_child(self, uid: int) -> None:
        """``haltChild``/``resetChild``: halt it if running, then reset it."""
        if self._status[uid] == RUNNING:
            self._halt(uid)
        self._set(uid, IDLE)

    def _halt(self, uid: int) -> None:
        """``haltNode``: a control node or decorator resets its children, then itself."""
        for child in self._children[uid]:
            self._reset_child(child)
        self._set(uid, IDLE)

    def _reset_children(self, uid: int, first: int = 0) -> None:
        for child in self._children[uid][first:]:
            self._reset_child(child)

    # -- what btcap does --------------------------------------------------------------
    def enter(self, uid: int) -> None:
        """``uid``'s tick starts."""
        stack = self._stack
        if stack:
            parent = stack[-1]
            self._last[parent] = self._children[parent].index(uid)
        stack.append(uid)
        kind = self._kind[uid]
        if not kind:
            return
        self._last[uid] = -1
        if kind == "SubTree":
            if self._status[uid] == IDLE:
                self._set(uid, RUNNING)
        elif kind != "RunOnce" or uid not in self._done_once:
            self._set(uid, RUNNING)

    def leave(self, uid: int, state: State) -> None:
        """``uid``'s tick returned ``state``: its own rules, its status, its parent's rules."""
        self._stack.pop()
        status = btcpp_status(state)
        kind = self._kind[uid]
        if kind and status in (SUCCESS, FAILURE) and not self._deco[uid]:
            self._finished(uid, kind, status)
        self._set(uid, status)
        if self._stack:
            self._child_gave(self._stack[-1], uid, status)

    def abandon(self) -> None:
        """The tick that started last raised instead of returning."""
        if self._stack:
            self._stack.pop()

    def _finished(self, uid: int, kind: str, status: int) -> None:
        """A control node gives a result: which children BehaviorTree.CPP resets."""
        last = self._last[uid]
        if kind == "SequenceWithMemory" and status == FAILURE:
            self._reset_children(uid, max(last, 0))
        elif kind == "IfThenElse" and last == 0:
            pass  # the condition failed and there is no else: nothing is reset
        else:
            self._reset_children(uid)

    def _child_gave(self, parent: int, child: int, status: int) -> None:
        kids = self._children[parent]
        kind = self._kind[parent]
        done = status in (SUCCESS, FAILURE)
        if self._deco[parent]:  # a decorator (or SubTree): resets a child that gave a result
            if done:
                if kind == "RunOnce":
                    self._done_once.add(parent)
                self._reset_child(child)
        elif kind in _REACTIVE and status == RUNNING:
            for other in kids:
                if other != child:
                    self._reset_child(other)
        elif kind == "WhileDoElse" and child == kids[0] and done and len(kids) == 3:
            self._reset_child(kids[2] if status == SUCCESS else kids[1])

    def root_done(self, root: int, state: State) -> None:
        """After a root tick: BehaviorTree.CPP's tree resets a root that gave a result."""
        self._stack.clear()
        if btcpp_status(state) in (SUCCESS, FAILURE):
            self._set(root, IDLE)

    def halt_tree(self, root: int) -> None:
        """``Tree::haltTree``: halt the root, then every node once more, root first."""
        self._stack.clear()
        self._halt(root)
        order = [root]
        while order:
            uid = order.pop()
            self._halt(uid)
            order.extend(reversed(self._children[uid]))
