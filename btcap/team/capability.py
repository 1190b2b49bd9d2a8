"""Capabilities: abstract skills (interfaces), their BT implementations, IO bridges, and
the capability node that binds an interface to the best implementation in the team.

An implementation is a subtree with an :class:`InputBridge` (whose outputs are the
capability's inputs) and optionally an :class:`OutputBridge` (whose inputs become the
capability's outputs). Each execution builds a fresh instance of that subtree, so it
leaves no trace when it ends.
"""

from __future__ import annotations

import enum
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar, Protocol

import msgspec

from btcap.bt.node import Leaf, Node
from btcap.bt.ports import Port, PortMap, check_value, normalize_ports, type_name
from btcap.bt.state import DONE, State, TreeError
from btcap.bt.tree import Tree
from btcap.bt.utility import Utility

if TYPE_CHECKING:
    from btcap.actors import TimeSource
    from btcap.team.mission import AssignmentRequest, MissionControl

__all__ = [
    "Capability",
    "CapabilityInterface",
    "Execution",
    "Implementation",
    "ImplementationRun",
    "InputBridge",
    "OutputBridge",
    "Precondition",
    "Scope",
]

_SUCCEEDED = State.SUCCEEDED
_FAILED = State.FAILED
_RUNNING = State.RUNNING
_UNASSIGNED = State.UNASSIGNED
_ASSIGNED = State.ASSIGNED


class CapabilityInterface:
    """An abstract skill: a name and typed inputs and outputs, no options.

    Two interfaces are the same when their :attr:`identity` (name plus port names and
    types) is; robots compare identities before bidding.
    """

    __slots__ = (
        "__weakref__",
        "_bridges",
        "_node_type",
        "description",
        "identity",
        "inputs",
        "name",
        "outputs",
    )

    def __init__(
        self,
        name: str,
        *,
        inputs: Mapping[str, Any] | None = None,
        outputs: Mapping[str, Any] | None = None,
        description: str = "",
        options: Mapping[str, Any] | None = None,
    ) -> None:
        if options:
            raise TreeError(
                f"capability interface {name!r}: interfaces take no options "
                f"(got {', '.join(options)}); make them inputs"
            )
        if not name.isidentifier():
            raise TreeError(f"capability interface name {name!r}: expected an identifier")
        self.name = name
        self.description = description
        self.inputs: PortMap = normalize_ports(dict(inputs or {}), f"interface {name} inputs")
        self.outputs: PortMap = normalize_ports(dict(outputs or {}), f"interface {name} outputs")
        self._node_type: type[Capability] | None = None
        self._bridges: tuple[type[InputBridge], type[OutputBridge]] | None = None
        # Compared on every call for bids, so computed once; the ports are fixed from here.
        ins = ",".join(f"{k}:{type_name(p.type)}" for k, p in sorted(self.inputs.items()))
        outs = ",".join(f"{k}:{type_name(p.type)}" for k, p in sorted(self.outputs.items()))
        self.identity: str = f"{self.name}({ins})->({outs})"

    def __repr__(self) -> str:
        return f"CapabilityInterface({self.identity})"

    def node_type(self) -> type[Capability]:
        """The node class for this capability (registered under the interface's name)."""
        if self._node_type is None:
            self._node_type = type(
                self.name,
                (Capability,),
                {"__slots__": (), "INTERFACE": self, "__doc__": self.description or None},
            )
        return self._node_type

    def bridge_types(self) -> tuple[type[InputBridge], type[OutputBridge]]:
        """Bridge node classes for files: ``<Name>Inputs`` and ``<Name>Outputs``."""
        if self._bridges is None:
            self._bridges = (
                type(f"{self.name}Inputs", (InputBridge,), {"__slots__": (), "INTERFACE": self}),
                type(f"{self.name}Outputs", (OutputBridge,), {"__slots__": (), "INTERFACE": self}),
            )
        return self._bridges

    def convert_inputs(self, values: Mapping[str, Any], where: str) -> dict[str, Any]:
        """Inputs from the wire, back to their declared types (missing ones: None)."""
        out: dict[str, Any] = {}
        for key, port in self.inputs.items():
            value = values.get(key)
            out[key] = (
                None if value is None else check_value(value, port.type, f"{where} input {key!r}")
            )
        return out


class _Bridge(Leaf):
    __slots__ = ("_iface",)
    INTERFACE: ClassVar[CapabilityInterface | None] = None

    def __init__(
        self, name: str | None = None, *, interface: CapabilityInterface | None = None, **kw: Any
    ) -> None:
        iface = interface or type(self).INTERFACE
        if iface is None:
            raise TreeError(f"{type(self).__name__}: needs the capability interface it bridges")
        self._iface = iface
        super().__init__(name, **kw)

    @property
    def interface(self) -> CapabilityInterface:
        return self._iface


class InputBridge(_Bridge):
    """Inside an implementation: publishes the capability's inputs as its outputs."""

    __slots__ = ()

    def declare_ports(self) -> None:
        self.output_ports = self._iface.inputs

    def feed(self, values: Mapping[str, Any]) -> None:
        outputs = self.outputs
        for key in outputs:
            outputs[key] = values.get(key)

    def on_tick(self) -> State:
        return _SUCCEEDED


class OutputBridge(_Bridge):
    """Inside an implementation: its inputs become the capability's outputs."""

    __slots__ = ()

    def declare_ports(self) -> None:
        self.input_ports = {k: Port(p.type, None) for k, p in self._iface.outputs.items()}

    def on_tick(self) -> State:
        return _SUCCEEDED


class Scope(enum.Enum):
    LOCAL = "local"
    REMOTE = "remote"


class Precondition(msgspec.Struct, frozen=True):
    """``capability`` must have succeeded on this robot (LOCAL) or on any member (REMOTE)."""

    capability: str
    scope: Scope = Scope.LOCAL


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


class Execution(Protocol):
    """The origin side of a running implementation, local or on another robot."""

    id: str
    robot: str

    def step(self, inputs: Mapping[str, Any]) -> tuple[State | None, dict[str, Any]]:
        """Send inputs, return the latest (state, outputs); state None: the executor is lost
        or the work moved (see :meth:`hand_over`)."""

    def pause(self) -> None: ...

    def cancel(self, reason: str) -> None: ...

    def hand_over(self) -> Execution | None:
        """The execution that takes over from this one (work moved to a cheaper robot)."""


class Capability(Node):
    """A capability in a tree: asks mission control for an executor, then runs it.

    unassigned (auction pending) -> assigned (executor found) -> running -> succeeded or
    failed. The result is kept until reset, so reactive parents do not re-run it. The
    assignment is fixed while assigned/running/paused; if the executor is lost the node
    goes back to unassigned and is re-assigned with its latest inputs, and it moves only
    when mission control's optional ``rebid_on_join`` policy found a cheaper robot.
    ``local_only`` restricts the auction to this robot.
    """

    __slots__ = ("_exclude", "_exec", "_request", "_result", "_retry_at", "assignments")
    INTERFACE: ClassVar[CapabilityInterface]
    OPTIONS: ClassVar[Any] = {
        "local_only": Port(bool, False, "only this robot may run it"),
        "retry_s": Port(float, 1.0, "clock seconds between auctions when nobody could run it"),
    }

    def __init__(self, name: str | None = None, **kwargs: Any) -> None:
        self._exec: Execution | None = None
        self._request: AssignmentRequest | None = None
        self._result: State | None = None
        self._retry_at = 0.0
        self._exclude: frozenset[str] = frozenset()
        self.assignments: list[str] = []  # robots that ran it, in order (for metrics)
        super().__init__(name, **kwargs)

    def declare_ports(self) -> None:
        iface = type(self).INTERFACE
        self.input_ports = iface.inputs
        self.output_ports = iface.outputs

    @classmethod
    def interface(cls) -> CapabilityInterface:
        return cls.INTERFACE

    @property
    def execution(self) -> Execution | None:
        return self._exec

    def _mission_control(self) -> MissionControl:
        from btcap.team.mission import MissionControl

        system = self.tree.system
        mc = system.lookup(MissionControl.PATH) if system is not None else None
        if not isinstance(mc, MissionControl):
            raise TreeError(
                f"capability {self.path!r}: the tree must be attached to a robot's actor "
                f"system running MissionControl (use btcap.Agent)"
            )
        return mc

    def on_tick(self) -> State:
        if self._result is not None:
            return self._result
        ex = self._exec
        if ex is None:
            return self._assign()
        state, outputs = ex.step(self.inputs)
        if state is None:
            self._exec = None
            nxt = ex.hand_over()
            if nxt is not None:  # moved to a cheaper robot that joined
                ex.cancel(f"moved to {nxt.robot}")
                self._exec = nxt
                self.assignments.append(nxt.robot)
                return _ASSIGNED
            # The executor is lost: re-assign with the latest inputs.
            self._exclude = frozenset({ex.robot})
            return self._assign()
        if outputs:
            mine = self.outputs
            for key, value in outputs.items():
                if key in mine:
                    mine[key] = value
        if state in DONE:
            self._exec = None
            ex.cancel("finished")
            self._result = _SUCCEEDED if state is _SUCCEEDED else _FAILED
            return self._result
        return _RUNNING if state is not _ASSIGNED else _ASSIGNED

    def _assign(self) -> State:
        req = self._request
        if req is None:
            now = self.clock.now()
            if now < self._retry_at:
                return _UNASSIGNED
            self._request = self._mission_control().request_assignment(
                self,
                dict(self.inputs),
                local_only=self.options["local_only"],
                exclude=self._exclude,
            )
            return _UNASSIGNED
        if not req.done:
            return _UNASSIGNED
        self._request = None
        if req.execution is None:
            self._retry_at = self.clock.now() + self.options["retry_s"]
            self._exclude = frozenset()
            return _UNASSIGNED
        self._exec = req.execution
        self.assignments.append(req.execution.robot)
        return _ASSIGNED

    def _drop(self, reason: str) -> None:
        if self._request is not None:
            self._request.cancel()
            self._request = None
        if self._exec is not None:
            self._exec.cancel(reason)
            self._exec = None

    def on_untick(self) -> None:
        if self._exec is not None:
            self._exec.pause()
        elif self._request is not None:
            # Paused before an executor was found: no work may start for a paused node,
            # so give the auction up; the next tick starts a fresh one.
            self._request.cancel()
            self._request = None

    def on_reset(self) -> None:
        self._drop("reset")
        self._result = None
        self._retry_at = 0.0
        self._exclude = frozenset()

    def on_shutdown(self) -> None:
        self._drop("shutdown")
        self._result = None

    def utility(self) -> Utility:
        return Utility()
