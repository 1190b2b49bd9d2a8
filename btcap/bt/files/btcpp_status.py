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
from btcap.bt.node import Node
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
    State.SKIPPED: SKIPPED,
}

_SUCCEEDED, _FAILED, _ERROR = State.SUCCEEDED, State.FAILED, State.ERROR
_SKIPPED = State.SKIPPED

#: Control nodes whose tick halts every child but the running one (BehaviorTree.CPP 4.8).
_REACTIVE = frozenset({"ReactiveSequence", "ReactiveFallback"})
#: Control nodes that reset nothing when all their children skipped (BehaviorTree.CPP 4.8).
_NO_RESET = frozenset({"Parallel", "ParallelAll", "Switch"})
#: Decorators that reset a child that returned SKIPPED (BehaviorTree.CPP 4.8).
_RESET_SKIPPED = frozenset({"Repeat", "RetryUntilSuccessful"})


def btcpp_status(state: State) -> int:
    """A btcap state as BehaviorTree.CPP's status: waiting and paused ones are RUNNING.

    SKIPPED is what a node returns; BehaviorTree.CPP never makes it a node's status (the
    node keeps the one it had), so no change in a log carries it."""
    return _STATUS.get(state, RUNNING)


#: What a node does when a child gives a result (BehaviorTree.CPP 4.8): nothing special,
#: a decorator or SubTree (resets the child), RunOnce (resets it and remembers), a
#: reactive control (a running child halts the others), WhileDoElse (a condition's
#: result halts the other branch).
_PLAIN, _DECO, _ONCE, _REACT, _WHILE = range(5)


class StatusFollower:
    """BehaviorTree.CPP's status of every node of one tree, moved by btcap's ticks.

    Every change is appended to :attr:`changes` as ``uid * 5 + status`` (the reader
    empties it). :meth:`wrap` makes a node class's ``tick`` tell the follower (it calls
    :meth:`enter` as a tick starts and :meth:`leave` with its result); call
    :meth:`root_done` after a root tick and :meth:`halt_tree` when the tree is halted
    from outside. Ticks nest as the tree does, so a node's parent is known from the
    tree, not from the calls.
    """

    __slots__ = (
        "_children",
        "_done_once",
        "_kind",
        "_last",
        "_out",
        "_parent",
        "_rule",
        "_status",
        "_uids",
        "changes",
    )

    def __init__(self, nodes: list[UidNode]) -> None:
        self.changes: list[int] = []
        self._out = self.changes.append
        size = len(nodes) + 1  # by uid; 0 is no node (the root's parent)
        self._status = [IDLE] * size
        self._children: list[tuple[int, ...]] = [()] * size
        self._kind = [""] * size  # BehaviorTree.CPP's name of a node with children
        self._rule = [_PLAIN] * size
        self._parent = [0] * size
        self._last = [0] * size  # the uid of the child ticked last
        uids = self._uids = {id(n): uid for uid, n, _ in nodes}
        for uid, n, _ in nodes:
            kids = [n.inner.root] if isinstance(n, Subtree) else n.children
            self._children[uid] = tuple(uids[id(c)] for c in kids)
            for child in self._children[uid]:
                self._parent[child] = uid
            kind = self._kind[uid] = btcpp_tag(n) if kids else ""
            if kind == "RunOnce":
                self._rule[uid] = _ONCE
            elif isinstance(n, Subtree) or type(n).MAX_CHILDREN == 1:
                self._rule[uid] = _DECO
            elif kind in _REACTIVE:
                self._rule[uid] = _REACT
            elif kind == "WhileDoElse":
                self._rule[uid] = _WHILE
        self._done_once: set[int] = set()  # RunOnce nodes whose child gave its result

    def _set(self, uid: int, status: int) -> None:
        if self._status[uid] != status:
            self._status[uid] = status
            self._out(uid * 5 + status)

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
        """``resetChildren``, from child ``first`` on (:meth:`_reset_child`, inlined: a
        control node's every result resets its children)."""
        status, out = self._status, self._out
        for child in self._children[uid][first:]:
            was = status[child]
            if was == RUNNING:
                self._halt(child)
            elif was != IDLE:
                status[child] = IDLE
                out(child * 5)

    # -- what btcap does --------------------------------------------------------------
    def enter(self, uid: int) -> None:
        """``uid``'s tick starts."""
        self._last[self._parent[uid]] = uid
        kind = self._kind[uid]
        if not kind:
            return
        status = self._status
        if kind == "SubTree":
            if status[uid] == IDLE:
                status[uid] = RUNNING
                self._out(uid * 5 + RUNNING)
        elif status[uid] != RUNNING and (kind != "RunOnce" or uid not in self._done_once):
            status[uid] = RUNNING
            self._out(uid * 5 + RUNNING)

    def leave(self, uid: int, state: State) -> None:
        """``uid``'s tick returned ``state``: its own rules, its status, its parent's rules."""
        if state is _SKIPPED:
            return self._skipped(uid)
        if state is _SUCCEEDED:
            code = SUCCESS
        elif state is _FAILED or state is _ERROR:
            code = FAILURE
        else:
            code = RUNNING
        rule = self._rule[uid]
        if code != RUNNING and self._kind[uid] and rule != _DECO and rule != _ONCE:
            self._finished(uid, code)  # a control node's result
        status = self._status
        if status[uid] != code:
            status[uid] = code
            self._out(uid * 5 + code)
        parent = self._parent[uid]
        if parent and self._rule[parent]:
            self._child_gave(parent, uid, code)

    def _skipped(self, uid: int) -> None:
        """``uid`` returned SKIPPED: BehaviorTree.CPP keeps its status (a RunOnce after its
        run; a control node whose children all skipped stays RUNNING, having reset them
        as after a result, except a Parallel); a Repeat or Retry resets it, a reactive
        parent halts it."""
        kind = self._kind[uid]
        if kind and self._rule[uid] not in (_DECO, _ONCE) and kind not in _NO_RESET:
            self._reset_children(uid)
        parent = self._parent[uid]
        if parent and (self._rule[parent] == _REACT or self._kind[parent] in _RESET_SKIPPED):
            self._reset_child(uid)

    def wrap(self, base: Callable[[Node], State], leaf: bool) -> Callable[[Node], State]:
        """A ``tick`` calling ``base`` (a node class's own) and telling the follower; for
        a ``leaf`` (no children, no rules of its own) :meth:`enter` and :meth:`leave`
        are inlined, as they run once per leaf tick. A tick that raises changes nothing."""
        uids, parents, last, status, rules = (
            self._uids,
            self._parent,
            self._last,
            self._status,
            self._rule,
        )
        out, gave, enter, leave = self._out, self._child_gave, self.enter, self.leave
        succeeded, failed, error = _SUCCEEDED, _FAILED, _ERROR

        def tick_leaf(node: Node) -> State:
            uid = uids[id(node)]
            parent = parents[uid]
            last[parent] = uid
            state = base(node)
            if state is succeeded:
                code = SUCCESS
            elif state is failed or state is error:
                code = FAILURE
            else:
                code = RUNNING
            if status[uid] != code:
                status[uid] = code
                out(uid * 5 + code)
            if rules[parent]:
                gave(parent, uid, code)
            return state

        def tick(node: Node) -> State:
            uid = uids[id(node)]
            enter(uid)
            state = base(node)
            leave(uid, state)
            return state

        return tick_leaf if leaf else tick

    def _finished(self, uid: int, status: int) -> None:
        """A control node gives a result: which children BehaviorTree.CPP resets."""
        kind = self._kind[uid]
        if kind == "SequenceWithMemory" and status == FAILURE:
            self._reset_children(uid, self._children[uid].index(self._last[uid]))
        elif kind != "IfThenElse" or self._last[uid] != self._children[uid][0]:
            self._reset_children(uid)
        # else IfThenElse's condition failed and there is no else branch: nothing is reset

    def _child_gave(self, parent: int, child: int, status: int) -> None:
        rule = self._rule[parent]
        done = status != RUNNING
        if rule in (_DECO, _ONCE):  # resets a child that gave a result
            if done:
                if rule == _ONCE:
                    self._done_once.add(parent)
                self._reset_child(child)
        elif rule == _REACT:
            if not done:
                for other in self._children[parent]:
                    if other != child:
                        self._reset_child(other)
        elif rule == _WHILE:
            kids = self._children[parent]
            if child == kids[0] and done and len(kids) == 3:
                self._reset_child(kids[2] if status == SUCCESS else kids[1])

    def root_done(self, root: int, state: State) -> None:
        """After a root tick: BehaviorTree.CPP's tree resets a root that gave a result."""
        if btcpp_status(state) in (SUCCESS, FAILURE):
            self._set(root, IDLE)

    def halt_tree(self, root: int) -> None:
        """``Tree::haltTree``: halt the root, then every node once more, root first."""
        self._halt(root)
        order = [root]
        while order:
            uid = order.pop()
            self._halt(uid)
            order.extend(reversed(self._children[uid]))
