"""Capability implementations: a BT subtree for one robot, its preconditions and its cost.

An implementation is a subtree with an
:class:`~btcap.team.capabilities.capability.InputBridge` (whose outputs are the
capability's inputs) and optionally an
:class:`~btcap.team.capabilities.capability.OutputBridge` (whose inputs become the capability's
outputs). Each execution builds a fresh instance of that subtree, so it leaves no trace
when it ends.
"""

from __future__ import annotations

import enum
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import msgspec

from btcap._enum import FastEnumType
from btcap.actors import TimeSource
from btcap.bt.node import Node
from btcap.bt.state import State, TreeError
from btcap.bt.tree import Tree
from btcap.bt.utility import Utility
from btcap.team.capabilities.capability import CapabilityInterface, InputBridge, OutputBridge

__all__ = ["BidFunction", "Implementation", "ImplementationRun", "Precondition", "Scope"]


class Scope(enum.Enum, metaclass=FastEnumType):
    LOCAL = "local"
    REMOTE = "remote"


class Precondition(msgspec.Struct, frozen=True):
    """``capability`` must have succeeded on this robot (LOCAL) or on any member (REMOTE)."""

    capability: str
    scope: Scope = Scope.LOCAL


#: The longest exception text a run's error report repeats.
_TEXT = 300

BidFunction = Callable[[Mapping[str, Any]], float | None]


class ImplementationRun:
    """One live instance of an implementation: a fresh tree plus its bridges."""

    __slots__ = ("implementation", "input_bridge", "output_bridge", "tree")

    def __init__(self, implementation: Implementation, tree: Tree) -> None:
        self.implementation = implementation
        self.tree = tree
        ins = [n for n in tree.nodes() if isinstance(n, InputBridge)]
        outs = [n for n in tree.nodes() if isinstance(n, OutputBridge)]
        iface = implementation.interface
        if len(ins) > 1 or len(outs) > 1:
            raise TreeError(
                f"implementation {implementation.name!r}: at most one bridge of each kind"
            )
        if iface.inputs and not ins:
            raise TreeError(f"implementation {implementation.name!r}: inputs need an InputBridge")
        if iface.outputs and not outs:
            raise TreeError(f"implementation {implementation.name!r}: outputs need an OutputBridge")
        for b in (*ins, *outs):
            if b.interface.identity != iface.identity:
                raise TreeError(
                    f"implementation {implementation.name!r}: bridge {b.path!r} is for "
                    f"{b.interface.identity}, expected {iface.identity}"
                )
        self.input_bridge = ins[0] if ins else None
        self.output_bridge = outs[0] if outs else None

    def step(self, inputs: Mapping[str, Any]) -> tuple[State, dict[str, Any]]:
        """Feed inputs, tick once, collect outputs: the per-tick IO bridge."""
        if self.input_bridge is not None:
            self.input_bridge.feed(inputs)
        state = self.tree.tick()
        out = self.output_bridge
        if out is None:
            return state, {}
        # Outputs flow back every tick, even while the bridge itself is not reached yet.
        values = out.inputs
        for key, src, port in out._pulls or ():
            values[key] = src.outputs[port]
        return state, dict(values)

    def why_error(self) -> str:
        """Which node of the run raised what (the first one found), for the origin of a
        run that ended in ERROR: its user is on another robot and sees no log of ours."""
        for node in self.tree.nodes():
            exc = node.error
            if exc is not None:
                text = str(exc)
                text = text if len(text) <= _TEXT else text[:_TEXT] + "..."
                return (
                    f"implementation {self.implementation.name!r}: node {node.path!r} "
                    f"({type(node).__name__}) raised {type(exc).__name__}: {text}"
                )
        return f"implementation {self.implementation.name!r} ended in ERROR"

    def pause(self) -> None:
        self.tree.untick()

    async def close(self) -> None:
        await self.tree.shutdown()


@dataclass(slots=True)
class Implementation:
    """A way to run an interface on one robot.

    ``build`` makes a fresh root node (or Tree) for every execution. ``bid`` adds an
    implementation-specific cost for given inputs (e.g. path length x cost factor +
    duration) to the subtree's utility; returning ``None`` means "cannot do these inputs".
    """

    name: str
    interface: CapabilityInterface
    build: Callable[[], Node | Tree]
    preconditions: tuple[Precondition, ...] = ()
    bid: BidFunction | None = None
    _utility: Utility | None = field(default=None, repr=False)

    def instantiate(self, clock: TimeSource | None = None) -> ImplementationRun:
        made = self.build()
        tree = made if isinstance(made, Tree) else Tree(made, name=self.name, clock=clock)
        if clock is not None:
            tree.clock = clock
        return ImplementationRun(self, tree)

    def utility(self) -> Utility:
        if self._utility is None:
            made = self.build()
            self._utility = (made if isinstance(made, Tree) else Tree(made)).utility()
        return self._utility

    def cost(self, inputs: Mapping[str, Any]) -> float | None:
        """The bid for these inputs, or None if this implementation cannot run them."""
        u = self.utility()
        if not u.can_execute:
            return None
        extra = self.bid(inputs) if self.bid is not None else 0.0
        if extra is None:
            return None
        return u.expected_cost + float(extra)

    def why_no_cost(self) -> str:
        """Whose decision a cost of None was, for the robot's decline: its bid function's
        (it returned None for these inputs) or its tree's (the utility says it cannot)."""
        if not self.utility().can_execute:
            return "cannot execute: its tree's utility says so (can_execute is False)"
        return "cannot execute these inputs: its bid function returned None"
