"""BehaviorTree.CPP v4's standard nodes and the btcap node each one becomes.

A node is mapped only where btcap's node decides the same way on every tick; nodes
whose behaviour btcap does not have are listed with the reason, so a file using one
is refused with a message saying what to use instead.

Three differences hold for every node and are not repeated per entry: a
BehaviorTree.CPP ``halt`` is a btcap untick, which keeps progress (a pre-empted branch
resumes where it was rather than starting over); loops over synchronous children
(RetryUntilSuccessful, Repeat) take one tick per attempt in btcap where
BehaviorTree.CPP loops within one tick: the results are the same, a tick later; and a
retry resets its child before the next attempt, where BehaviorTree.CPP only sets the
failed child idle, so a SequenceWithMemory under RetryUntilSuccessful starts over at
its first child in btcap but resumes at the child that failed in BehaviorTree.CPP.
Parallel is mapped although it decides once per tick (failure winning a tie) where
BehaviorTree.CPP decides after each child (success first): the two differ only when
several children finish in the same tick.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

from btcap.errors import BtcapError

__all__ = ["STANDARD", "UNSUPPORTED", "Standard", "parse_bool", "parse_int"]


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


def _no_skip(text: str) -> None:
    if parse_bool(text):
        raise MappingError(
            "then_skip=true returns SKIPPED, which btcap does not have; "
            "then_skip=false (repeat the first result) maps to btcap's RunOnce"
        )


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


STANDARD: dict[str, Standard] = {
    # btcap's control nodes have BehaviorTree.CPP's names and decide as they do.
    "Sequence": Standard("Sequence"),
    "AsyncSequence": Standard("AsyncSequence"),
    "AsyncFallback": Standard("AsyncFallback"),
    "SequenceWithMemory": Standard("SequenceWithMemory"),
    "Fallback": Standard("Fallback"),
    "ReactiveSequence": Standard("ReactiveSequence"),
    "ReactiveFallback": Standard("ReactiveFallback"),
    "Parallel": Standard(
        "Parallel",
        {
            "success_count": ("success_threshold", parse_int),
            "failure_count": ("failure_threshold", parse_int),
        },
        fixed={"failure_threshold": 1},
    ),
    "WhileDoElse": Standard("WhileDoElse"),
    "Inverter": Standard("Inverter"),
    "ForceSuccess": Standard("ForceSuccess"),
    "ForceFailure": Standard("ForceFailure"),
    "KeepRunningUntilFailure": Standard("SuccessIsRunning"),
    "RetryUntilSuccessful": Standard(
        "RepeatUntilSuccess", {"num_attempts": ("max_attempts", _attempts)}, ("num_attempts",)
    ),
    "Repeat": Standard("Repeat", {"num_cycles": ("times", _cycles)}, ("num_cycles",)),
    "Timeout": Standard("Timeout", {"msec": ("seconds", _timeout)}, ("msec",)),
    "Delay": Standard("Delay", {"delay_msec": ("seconds", _seconds)}, ("delay_msec",)),
    "RunOnce": Standard(
        "RunOnce", {"then_skip": ("", _no_skip)}, ("then_skip",), fixed={"forever": True}
    ),
    "AlwaysSuccess": Standard("AlwaysSuccess"),
    "AlwaysFailure": Standard("AlwaysFailure"),
    "Sleep": Standard("Wait", {"msec": ("seconds", _seconds)}, ("msec",)),
}

#: Standard nodes btcap cannot run as BehaviorTree.CPP does, and why.
UNSUPPORTED: dict[str, str] = {
    "IfThenElse": "it checks its condition only until a branch runs; btcap's IfThenElse "
    "re-checks it every tick, as BehaviorTree.CPP's WhileDoElse does (use WhileDoElse)",
    "ParallelAll": "it waits for every child; btcap's Parallel decides as soon as a "
    "threshold is met (use Parallel)",
    "Script": "btcap has no scripting language; use a node type of your own",
    "ScriptCondition": "btcap has no scripting language; use Compare or a node of your own",
    "Precondition": "btcap has no scripting language; use WhileDoElse with a condition node",
    "UnsetBlackboard": "btcap wires node outputs to inputs; there is no blackboard entry to unset",
    "SkipUnlessUpdated": "btcap has no SKIPPED state",
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
