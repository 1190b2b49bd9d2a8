"""BehaviorTree.CPP v4's standard nodes and the btcap node each one becomes.

A node is mapped only where btcap's node decides the same way on every tick, or with
a difference named in :data:`DIFFERENCES` (``Standard.differs``); nodes whose behaviour
btcap does not have are listed with the reason, so a file using one
is refused with a message saying what to use instead. :func:`node_table` renders the
whole list (docs/btcpp.md), and tests/btcap/bt/test_btcpp_oracle.py ticks random trees
of the mapped nodes in btcap and in BehaviorTree.CPP 4.8 itself, allowing only the
:data:`DIFFERENCES` below.

The loops of RetryUntilSuccessful and Repeat: in BehaviorTree.CPP 4.8 a child that gives
its result at once already takes one tick per attempt, as in btcap; only a child that
was running and now asks for another attempt is ticked again within the same tick
there, and in the next tick in btcap.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

from btcap.bt.scripting import ScriptSyntaxError, parse
from btcap.errors import BtcapError

__all__ = [
    "BUILTINS",
    "DIFFERENCES",
    "STANDARD",
    "UNSUPPORTED",
    "V3_NAMES",
    "MappingError",
    "Standard",
    "node_table",
    "parse_bool",
    "parse_int",
    "script_code",
]


class MappingError(BtcapError, ValueError):
    """A standard node's attribute has a value btcap cannot express."""


def parse_int(text: str) -> int:
    try:
        return int(text.strip())
    except ValueError:
        raise MappingError(f"expected an integer, got {text!r}") from None


def parse_bool(text: str) -> bool:
    value = text.strip().lower()
    if value in ("true", "1"):
        return True
    if value in ("false", "0"):
        return False
    raise MappingError(f"expected true or false, got {text!r}")


def _seconds(text: str) -> float:
    ms = parse_int(text)
    if ms < 0:
        raise MappingError(f"expected milliseconds >= 0, got {ms}")
    return ms / 1000.0


def _timeout(text: str) -> float:
    seconds = _seconds(text)
    if seconds == 0:
        raise MappingError(
            "msec=0 is no timeout in BehaviorTree.CPP (it starts no timer), where btcap's "
            "Timeout would fail at once; leave the Timeout out"
        )
    return seconds


def _attempts(text: str) -> int | None:
    n = parse_int(text)
    if n == -1:
        return None
    if n < 1:
        raise MappingError(f"expected a count >= 1 or -1 (for ever), got {n}")
    return n


def _cycles(text: str) -> int:
    n = parse_int(text)
    if n != -1 and n < 1:
        raise MappingError(f"expected a count >= 1 or -1 (for ever), got {n}")
    return n


def script_code(text: str) -> str:
    """A script, parsed now so a syntax error names its column (nodes parse it once more
    from the cache)."""
    try:
        parse(text)
    except ScriptSyntaxError as exc:
        raise MappingError(f"{exc} in script {text!r}") from None
    return text


def _else(text: str) -> str:
    if text not in ("SUCCESS", "FAILURE", "RUNNING", "SKIPPED"):
        raise MappingError(f"expected SUCCESS, FAILURE, RUNNING or SKIPPED, got {text!r}")
    return text


@dataclasses.dataclass(frozen=True)
class Standard:
    """A standard node: the btcap type, and per attribute the btcap option and converter.

    A converter returning None sets no option (the attribute only selects behaviour that
    btcap has anyway, like ``then_skip=false``). ``required`` attributes have no default
    in BehaviorTree.CPP; ``fixed`` are options BehaviorTree.CPP's defaults imply.
    """

    btcap: str
    attrs: dict[str, tuple[str, Callable[[str], Any]]] = dataclasses.field(default_factory=dict)
    required: tuple[str, ...] = ()
    fixed: dict[str, Any] = dataclasses.field(default_factory=dict)
    #: Why a ``required`` attribute BehaviorTree.CPP has a default for must be written.
    why_required: str = ""
    #: Keys of :data:`DIFFERENCES` this node shows; empty: it decides as BehaviorTree.CPP.
    differs: tuple[str, ...] = ()
    #: The btcap type reading the ``required`` attribute as an input where it names a
    #: blackboard entry (:mod:`btcap.bt.read_options`); empty: it must be a literal.
    from_input: str = ""


#: Where a mapped node may decide differently from BehaviorTree.CPP 4.8, by key (the
#: differential test names each one; nothing else is allowed to differ).
DIFFERENCES: dict[str, str] = {
    "halt_keeps_progress": "A BehaviorTree.CPP halt is a btcap untick, which keeps "
    "progress: a pre-empted Sequence, Fallback, AsyncSequence, AsyncFallback or Parallel "
    "resumes where it was (a ParallelAll too), IfThenElse keeps the branch it chose, and "
    "RetryUntilSuccessful/Repeat keep their counts, where "
    "BehaviorTree.CPP starts them over (SequenceWithMemory keeps its position in both).",
    "loop_after_running": "When a child that was running fails under RetryUntilSuccessful "
    "(or succeeds under Repeat) and attempts remain, BehaviorTree.CPP ticks it again "
    "within the same tick; btcap starts the next attempt in the next tick. A child that "
    "gives its result at once takes one tick per attempt in both.",
    "memory_reset_by_retry": "Before another attempt a retry or repeat resets its child, "
    "and a Parallel starting over resets the children it halted, so a SequenceWithMemory "
    "below them starts over at its first child in btcap; BehaviorTree.CPP's resumes at "
    "the child that failed.",
    "action_result_kept": "A BehaviorTree.CPP asynchronous action (StatefulActionNode) "
    "that gave a result gives it again, without running, if ticked before its parent "
    "resets it: WhileDoElse's condition while a branch runs, IfThenElse's after it failed "
    "without an else branch. A btcap leaf runs on every tick it gets. Condition nodes "
    "and synchronous actions run on every tick in both.",
    "script_errors": "Scripts follow BehaviorTree.CPP 4.8's grammar, types and "
    "conversions (docs/btcpp.md, Scripts). A script that fails while running (an entry "
    "without a value, a conversion refused) fails its node with the reason, where "
    "BehaviorTree.CPP throws out of the tick; a syntax error, or an assignment to "
    "something other than an entry, is refused when the file loads, where "
    "BehaviorTree.CPP refuses it when the tree is created or ticked.",
    "skipped_condition": "An IfThenElse or WhileDoElse whose condition is skipped "
    "(_skipIf, _while, a RunOnce after its run) has no branch to run: BehaviorTree.CPP 4.8 "
    "throws out of the tick (or its tickWhileRunning keeps ticking an IDLE root); btcap "
    "fails the node with that reason.",
    "parallel_decides_per_child": "BehaviorTree.CPP's Parallel checks its thresholds after "
    "each child and stops ticking once decided (success checked first); btcap's ticks "
    "every unfinished child, then decides (failure wins a tie). They differ only when "
    "several children finish in the same tick.",
}

STANDARD: dict[str, Standard] = {
    # btcap's control nodes have BehaviorTree.CPP's names and decide as they do.
    "Sequence": Standard("Sequence", differs=("halt_keeps_progress",)),
    "AsyncSequence": Standard("AsyncSequence", differs=("halt_keeps_progress",)),
    "AsyncFallback": Standard("AsyncFallback", differs=("halt_keeps_progress",)),
    "SequenceWithMemory": Standard("AsyncSequenceWithMemory", differs=("memory_reset_by_retry",)),
    "Fallback": Standard("Fallback", differs=("halt_keeps_progress",)),
    "ReactiveSequence": Standard("ReactiveSequence"),
    "ReactiveFallback": Standard("ReactiveFallback"),
    "Parallel": Standard(
        "Parallel",
        {
            "success_count": ("success_threshold", parse_int),
            "failure_count": ("failure_threshold", parse_int),
        },
        fixed={"failure_threshold": 1},
        differs=("parallel_decides_per_child", "halt_keeps_progress"),
    ),
    "ParallelAll": Standard(
        "ParallelAll",
        {"max_failures": ("max_failures", parse_int)},
        differs=("halt_keeps_progress",),
    ),
    "WhileDoElse": Standard("WhileDoElse", differs=("action_result_kept",)),
    "IfThenElse": Standard(
        "LatchedIfThenElse", differs=("halt_keeps_progress", "action_result_kept")
    ),
    "Inverter": Standard("Inverter"),
    "ForceSuccess": Standard("ForceSuccess"),
    "ForceFailure": Standard("ForceFailure"),
    "KeepRunningUntilFailure": Standard("SuccessIsRunning"),
    "RetryUntilSuccessful": Standard(
        "RepeatUntilSuccess",
        {"num_attempts": ("max_attempts", _attempts)},
        ("num_attempts",),
        differs=("loop_after_running", "halt_keeps_progress"),
        from_input="RepeatUntilSuccessFromInput",
    ),
    "Repeat": Standard(
        "Repeat",
        {"num_cycles": ("times", _cycles)},
        ("num_cycles",),
        differs=("loop_after_running", "halt_keeps_progress"),
        from_input="RepeatFromInput",
    ),
    "Timeout": Standard(
        "Timeout", {"msec": ("seconds", _timeout)}, ("msec",), from_input="TimeoutFromInput"
    ),
    "Delay": Standard(
        "Delay", {"delay_msec": ("seconds", _seconds)}, ("delay_msec",), from_input="DelayFromInput"
    ),
    "RunOnce": Standard(
        "RunOnce",
        {"then_skip": ("then_skip", parse_bool)},
        fixed={"forever": True, "then_skip": True},
    ),
    "AlwaysSuccess": Standard("AlwaysSuccess"),
    "AlwaysFailure": Standard("AlwaysFailure"),
    "Sleep": Standard(
        "Wait", {"msec": ("seconds", _seconds)}, ("msec",), from_input="WaitFromInput"
    ),
    "Script": Standard(
        "Script", {"code": ("code", script_code)}, ("code",), differs=("script_errors",)
    ),
    "ScriptCondition": Standard(
        "ScriptCondition", {"code": ("code", script_code)}, ("code",), differs=("script_errors",)
    ),
    "Precondition": Standard(
        "ScriptPrecondition",
        {"if": ("if", script_code), "else": ("else", _else)},
        ("if",),
        differs=("script_errors",),
    ),
}

#: BehaviorTree.CPP v3's node names that v4 renamed, with the v4 name.
V3_NAMES: dict[str, str] = {"SequenceStar": "SequenceWithMemory"}

#: Standard nodes btcap cannot run as BehaviorTree.CPP does, and why.
UNSUPPORTED: dict[str, str] = {
    "WasEntryUpdated": "btcap has no blackboard update stamps",
    "UnsetBlackboard": "btcap's blackboard entries keep their last value; nothing unsets one",
    "TryCatch": "btcap has no node that runs a cleanup child after its "
    "others failed or were halted; use Fallback(Sequence(...), Sequence(cleanup, AlwaysFailure))",
    "SkipUnlessUpdated": "btcap has no blackboard update stamps",
    "WaitValueUpdate": "btcap has no blackboard update stamps",
    "ManualSelector": "it asks a person on a terminal; btcap trees never block on input",
    "SubTreePlus": "it is BehaviorTree.CPP v3; in format 4 use SubTree with _autoremap",
    **{
        f"Switch{n}": "its cases are strings compared by BehaviorTree.CPP's own rules; "
        "use btcap's Switch with typed cases"
        for n in range(2, 7)
    },
    **{
        f"Loop{kind}": "btcap has no queue ports; loop with Repeat over a node of your own"
        for kind in ("Int", "Double", "String", "Bool")
    },
}

#: Elements the XML reader handles itself (not node types), with what they become.
SPECIAL: dict[str, str] = {
    "SubTree": "a btcap Subtree; ports remapped by attribute, literal or _autoremap",
    "SetBlackboard": "a Constant typed by the port that reads the entry",
}

#: BehaviorTree.CPP 4.8's built-in node types (what its factory registers), in its order.
BUILTINS: tuple[str, ...] = (
    *("Sequence", "AsyncSequence", "SequenceWithMemory", "Fallback", "AsyncFallback"),
    *("ReactiveSequence", "ReactiveFallback", "Parallel", "ParallelAll"),
    *("IfThenElse", "WhileDoElse", *(f"Switch{n}" for n in range(2, 7))),
    *("Inverter", "ForceSuccess", "ForceFailure", "KeepRunningUntilFailure"),
    *("RetryUntilSuccessful", "Repeat", "Timeout", "Delay", "RunOnce", "Precondition"),
    *("SkipUnlessUpdated", "WaitValueUpdate", *(f"Loop{k}" for k in ("Int", "Double"))),
    *("LoopString", "LoopBool", "AlwaysSuccess", "AlwaysFailure", "Sleep", "Script"),
    *("ScriptCondition", "SetBlackboard", "UnsetBlackboard", "WasEntryUpdated", "SubTree"),
    *("ManualSelector", "SubTreePlus", "TryCatch"),
)


def node_table() -> str:
    """Markdown: every built-in, mapped exactly / with a stated difference / refused."""
    rows = ["| BehaviorTree.CPP node | btcap | how |", "|---|---|---|"]
    for name in BUILTINS:
        if name in STANDARD:
            std = STANDARD[name]
            how = ", ".join(f"[{d}](#{d})" for d in std.differs) or "exact"
            if name in ("Timeout", "Delay", "Sleep"):
                how += " (on the clock; not in the differential test)"
            rows.append(f"| `{name}` | `{std.btcap}` | {how} |")
        elif name in SPECIAL:
            rows.append(f"| `{name}` | {SPECIAL[name]} | read by the loader (docs/trees.md) |")
        else:
            rows.append(f"| `{name}` | refused | {UNSUPPORTED[name]} |")
    notes = [f"### {key}\n\n{text}\n" for key, text in DIFFERENCES.items()]
    return "\n".join(rows) + "\n\n" + "\n".join(notes)
