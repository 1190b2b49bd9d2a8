"""Capabilities: abstract skills (interfaces), the IO bridges inside their
implementations, and the capability node that binds an interface at run time to the
best implementation in the team.

The node needs only an :class:`Assigner` from its robot (mission control); it never
imports it, so the layers stay one-way.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar, Protocol, runtime_checkable

from btcap.actors.services import Service
from btcap.bt.node import Leaf, Node
from btcap.bt.ports import Port, PortMap, normalize_ports, type_name
from btcap.bt.state import DONE, State, TreeError
from btcap.bt.utility import Utility
from btcap.team.capabilities.conversion import Where, convert
from btcap.team.capabilities.execution import AssignmentRequest, Execution
from btcap.team.capabilities.unassignable import nobody_able, tell_nobody, tell_timeout
from btcap.transports.log import get_logger

__all__ = [
    "ASSIGNER",
    "ASSIGNER_PATH",
    "Assigner",
    "Capability",
    "CapabilityInterface",
    "InputBridge",
    "OutputBridge",
]

log = get_logger(__name__)

#: Where a robot's actor system runs its :class:`Assigner` (mission control).
ASSIGNER_PATH = "mission_control"

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

    def convert_inputs(self, values: Mapping[str, Any], where: Where) -> dict[str, Any]:
        """Inputs from the wire, back to their declared types (missing ones: None).
        ``where`` (or what it returns: formatted only for an error) names them."""
        return convert(self.inputs, values, where, "input")

    def convert_outputs(self, values: Mapping[str, Any], where: Where) -> dict[str, Any]:
        """Outputs from the wire, back to their declared types (missing ones: None)."""
        return convert(self.outputs, values, where, "output")


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


@runtime_checkable
class Assigner(Protocol):
    """What a capability node needs from its robot: an executor for its inputs, and a
    count of the team changes that may let waiting work go (a robot came free, joined)."""

    changes: int

    def request_assignment(
        self,
        node: Capability,
        inputs: dict[str, Any],
        *,
        local_only: bool = False,
        exclude: frozenset[str] = frozenset(),
    ) -> AssignmentRequest: ...


#: The robot's :class:`Assigner` among its actor system's services (its mission control).
ASSIGNER: Service[Assigner] = Service("assigner")


class Capability(Node):
    """A capability in a tree: asks mission control for an executor, then runs it.

    unassigned (auction pending) -> assigned (executor found) -> running -> succeeded or
    failed. The result is kept until reset, so reactive parents do not re-run it. The
    assignment is fixed while assigned/running/paused; if the executor is lost the node
    goes back to unassigned and is re-assigned with its latest inputs, and it moves only
    when mission control's optional ``rebid_on_join`` policy found a cheaper robot.
    ``local_only`` restricts the auction to this robot.

    While nobody can take it, it stays unassigned (the team may change) and says so: a
    log warning with each robot's reason after the first failed auction, then after the
    2nd, 4th, 8th..., and once an :class:`~btcap.bt.state.UnassignableWarning`, which
    Python shows by default. ``assignment_timeout_s`` (clock seconds, 0: wait for ever)
    turns a wait that long into a failure the tree can handle.
    """

    __slots__ = (
        "_exclude",
        "_exec",
        "_request",
        "_result",
        "_retry_at",
        "_seen_changes",
        "_waiting_since",
        "_waits",
        "assignments",
    )
    INTERFACE: ClassVar[CapabilityInterface]
    OPTIONS: ClassVar[Any] = {
        "local_only": Port(bool, False, "only this robot may run it"),
        "retry_s": Port(
            float,
            10.0,
            "clock seconds before auctioning again when nobody could run it and "
            "nothing changed in the team (a robot coming free or joining retries at once)",
        ),
        "assignment_timeout_s": Port(
            float, 0.0, "fail after this many clock seconds unassigned (0: wait for ever)"
        ),
    }

    def __init__(self, name: str | None = None, **kwargs: Any) -> None:
        self._exec: Execution | None = None
        self._request: AssignmentRequest | None = None
        self._result: State | None = None
        self._retry_at = 0.0
        self._seen_changes = 0
        self._exclude: frozenset[str] = frozenset()
        self._waits = 0  # auctions in a row that found nobody
        self._waiting_since: float | None = None
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

    def _mission_control(self) -> Assigner:
        system = self.tree.system
        mc = system.services.get(ASSIGNER) if system is not None else None
        if mc is None:
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
                self.tree.nudge()  # its inputs go out at once, not a period later
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
            since = self._waiting_since
            if since is None:
                self._waiting_since = since = now
            timeout = self.options["assignment_timeout_s"]
            if timeout > 0 and now - since >= timeout:
                self._give_up(now - since)
                return _FAILED
            mc = self._mission_control()
            if now < self._retry_at and mc.changes == self._seen_changes:
                return _UNASSIGNED  # nothing changed since nobody could take it
            self._seen_changes = mc.changes
            self._request = mc.request_assignment(
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
            self._waits += 1
            if self._waits & (self._waits - 1) == 0:  # the 1st, 2nd, 4th, 8th ... time
                iface = type(self).INTERFACE.name
                # Waiting for a busy robot is routine; nobody able to do it is news.
                news = nobody_able(req.why)
                (log.warning if news else log.info)(
                    "capability.unassigned",
                    node=self.path,
                    capability=iface,
                    auctions=self._waits,
                    why=req.why,
                )
                if news:
                    tell_nobody(self, iface, req.why, self.options["assignment_timeout_s"])
            return _UNASSIGNED
        self._exec = req.execution
        self._waits, self._waiting_since = 0, None
        self.assignments.append(req.execution.robot)
        self.tree.nudge()  # its inputs go out (a run of our own starts) at once
        return _ASSIGNED

    def _give_up(self, waited: float) -> None:
        self._result = _FAILED
        log.warning(
            "capability.assignment_timeout",
            node=self.path,
            capability=type(self).INTERFACE.name,
            waited_s=round(waited, 3),
        )
        timeout = self.options["assignment_timeout_s"]
        tell_timeout(self, type(self).INTERFACE.name, timeout, self._waits)

    def _drop(self, reason: str) -> None:
        if self._request is not None:
            self._request.cancel()
            self._request = None
        if self._exec is not None:
            self._exec.cancel(reason)
            self._exec = None

    def on_untick(self) -> None:
        ex = self._exec
        if ex is not None:
            if ex.moving():
                # Adopted as it pauses: in an exchange the other task waits behind this
                # one's old run, which only the adoption releases (it must not wait for
                # this node's next tick, which may never come).
                nxt = ex.hand_over()
                if nxt is not None:
                    ex.cancel(f"moved to {nxt.robot}")
                    self._exec = ex = nxt
                    self.assignments.append(nxt.robot)
            ex.pause()
            return
        if self._request is not None:
            # Paused before an executor was found: no work may start for a paused node,
            # so give the auction up; the next tick starts a fresh one.
            self._request.cancel()
            self._request = None
        self._waiting_since = None  # paused time is no waiting: the timeout starts again

    def on_reset(self) -> None:
        self._drop("reset")
        self._result = None
        self._retry_at = 0.0
        self._exclude = frozenset()
        self._waits, self._waiting_since = 0, None

    def on_shutdown(self) -> None:
        self._drop("shutdown")
        self._result = None

    def utility(self) -> Utility:
        return Utility()
