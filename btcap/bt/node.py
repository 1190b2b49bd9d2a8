"""The node model: every BT node is an actor with typed ports and a small life cycle.

Ticking a local tree is a chain of plain method calls (the actor runtime's fast path);
the same actions are also messages (:mod:`btcap.bt.messages`) so a node can be driven from
another actor of its system. They are ``local_only``: from another process or robot they
are refused (:class:`~btcap.actors.errors.Refused`), whatever sender they name.
"""

from __future__ import annotations

from collections.abc import Callable, Coroutine, Iterator, Sequence
from typing import TYPE_CHECKING, Any, ClassVar

from btcap.actors import Actor, handler
from btcap.bt.empty import NO_CHILDREN, NO_VALUES
from btcap.bt.host import TreeHost
from btcap.bt.messages import NodeStatus, Reset, Setup, Shutdown, Tick, Untick
from btcap.bt.ports import PortMap, check_options, check_port, check_wired, normalize_ports
from btcap.bt.specialize import own_copies
from btcap.bt.state import ACTIVE, IllegalTransition, NodeErrorWarning, State, TreeError
from btcap.bt.told import tell_error
from btcap.bt.utility import Utility
from btcap.transports.log import get_logger

if TYPE_CHECKING:
    import asyncio

    from btcap.actors import TimeSource

__all__ = ["Leaf", "Node", "Observer", "TreeHost"]

log = get_logger(__name__)

#: Called as ``observer(node, old_state, new_state)`` whenever a node changes state.
Observer = Callable[["Node", State, State], None]


_UNINIT = State.UNINITIALIZED
_SHUTDOWN = State.SHUTDOWN
_IDLE = State.IDLE
_PAUSED = State.PAUSED
_ERROR = State.ERROR
#: ``ACTIVE`` as a tuple: ``in`` compares by identity, without Enum's Python-level __hash__.
_ACTIVE = (State.RUNNING, State.ASSIGNED, State.UNASSIGNED)


class Node(Actor):
    """Base class of every node.

    Subclasses declare ports as class attributes (``INPUTS``, ``OUTPUTS``, ``OPTIONS``:
    dicts of name to type or :class:`~btcap.bt.ports.Port`) and implement :meth:`on_tick`;
    they may override :meth:`on_setup`, :meth:`on_untick`, :meth:`on_reset`,
    :meth:`on_shutdown` and :meth:`utility`. Options are keyword arguments of the
    constructor and are checked against their declared types.
    """

    __slots__ = (
        "_gate",
        "_pulls",
        "_ready",
        "_tree",
        "_watch",
        "children",
        "error",
        "input_ports",
        "inputs",
        "name",
        "options",
        "output_ports",
        "outputs",
        "parent_node",
        "state",
    )

    # Declared as plain types or Ports (``{"x": float}``); normalized to PortMaps on
    # subclass creation, hence the loose annotation.
    INPUTS: ClassVar[dict[str, Any]] = {}
    OUTPUTS: ClassVar[dict[str, Any]] = {}
    OPTIONS: ClassVar[dict[str, Any]] = {}
    #: Bounds on the number of children; ``None`` means unbounded.
    MIN_CHILDREN: ClassVar[int] = 0
    MAX_CHILDREN: ClassVar[int | None] = 0

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        for attr in ("INPUTS", "OUTPUTS", "OPTIONS"):
            if attr in cls.__dict__:
                setattr(
                    cls, attr, normalize_ports(cls.__dict__[attr], f"{cls.__qualname__}.{attr}")
                )
        own_copies(cls, Node, ("tick", "reset", "untick"))  # the hot actions

    def __init__(
        self,
        name: str | None = None,
        *,
        children: Sequence[Node] = (),
        inputs: dict[str, Any] | None = None,
        **options: Any,
    ) -> None:
        super().__init__()
        cls = type(self)
        self.name: str = name if name is not None else cls.__name__
        if not self.name or "/" in self.name or "." in self.name:
            raise TreeError(
                f"node name {self.name!r}: expected a non-empty name without '/' or '.'"
            )
        self.state = _UNINIT
        self.error: BaseException | None = None
        self.parent_node: Node | None = None
        self._tree: TreeHost | None = None
        self._watch: Observer | None = None
        self._pulls: list[tuple[str, Node, str]] | None = None
        self._ready = False
        self._gate: bool | tuple[Any, ...] | None = True
        # Nothing declared, nothing held: shared unwritable empties (see btcap.bt.empty).
        self.options = self._check_options(options) if options or cls.OPTIONS else NO_VALUES
        self.input_ports: PortMap = cls.INPUTS
        self.output_ports: PortMap = cls.OUTPUTS
        self.declare_ports()
        ins, outs = self.input_ports, self.output_ports
        self.inputs: dict[str, Any] = (
            {n: p.default_value() for n, p in ins.items()} if ins else NO_VALUES
        )
        self.outputs: dict[str, Any] = dict.fromkeys(outs) if outs else NO_VALUES
        if inputs:
            for key, value in inputs.items():
                self.set_input(key, value)
        self.children: list[Node] = [] if cls.MAX_CHILDREN != 0 else NO_CHILDREN
        seen: set[str] = set()
        for child in children:
            if child.name in seen:
                raise TreeError(f"node {self.name!r} already has a child named {child.name!r}")
            seen.add(child.name)
            self.add_child(child, _unique=True)

    # -- declaration ------------------------------------------------------------------
    def declare_ports(self) -> None:
        """Override to compute ``input_ports``/``output_ports`` from options."""

    def check_children(self) -> None:
        """Raise TreeError if the options cannot work with the current children.

        Called when a tree is validated or loaded, so a node whose configuration depends on
        its children (a Parallel's thresholds) is rejected before it ever ticks.
        """

    def _check_options(self, given: dict[str, Any]) -> dict[str, Any]:
        return check_options(type(self).OPTIONS, given, self.name, type(self).__name__)

    def set_input(self, key: str, value: Any) -> None:
        """Give an input a constant value (checked against its type)."""
        port = self.input_ports.get(key)
        if port is None:
            raise TreeError(
                f"node {self.name!r} ({type(self).__name__}) has no input {key!r}; "
                f"inputs: {', '.join(self.input_ports) or 'none'}"
            )
        self.inputs[key] = check_port(value, port, f"node {self.name!r} input {key!r}")

    # -- structure --------------------------------------------------------------------
    def add_child(self, child: Node, index: int | None = None, *, _unique: bool = False) -> Node:
        limit = type(self).MAX_CHILDREN
        if limit is not None and len(self.children) >= limit:
            raise TreeError(
                f"node {self.name!r} ({type(self).__name__}) takes at most {limit} children"
            )
        if child.parent_node is not None:
            raise TreeError(f"node {child.name!r} already has parent {child.parent_node.name!r}")
        if not _unique and any(c.name == child.name for c in self.children):
            raise TreeError(f"node {self.name!r} already has a child named {child.name!r}")
        if self.state not in (_UNINIT, _IDLE, _SHUTDOWN, State.SUCCEEDED, State.FAILED):
            raise IllegalTransition(
                f"cannot add a child to {self.name!r} while it is {self.state.value}"
            )
        child.parent_node = self
        if index is None:
            self.children.append(child)
        else:
            self.children.insert(index, child)
        if self._tree is not None:
            try:
                self._tree._adopt(child)
            except BaseException:
                self.children.remove(child)
                child.parent_node = None
                raise
        if self._ready and not child._ready:
            child.setup()  # joining a set-up tree: ready to be ticked like its siblings
        return child

    def remove_child(self, child: Node) -> None:
        if child.parent_node is not self:
            raise TreeError(f"node {child.name!r} is not a child of {self.name!r}")
        if child.state in ACTIVE:
            raise IllegalTransition(f"cannot remove {child.name!r} while it is {child.state.value}")
        if self._tree is not None:
            self._tree._release(child)
        self.children.remove(child)
        child.parent_node = None

    @property
    def path(self) -> str:
        """Slash-separated names from the root: how files and wires name this node."""
        parts = [self.name]
        node = self.parent_node
        while node is not None:
            parts.append(node.name)
            node = node.parent_node
        return "/".join(reversed(parts))

    def walk(self) -> Iterator[Node]:
        """This node and all below it, depth first."""
        yield self
        for c in self.children:
            yield from c.walk()

    @property
    def tree(self) -> TreeHost:
        if self._tree is None:
            raise TreeError(f"node {self.name!r} is not part of a Tree")
        return self._tree

    @property
    def clock(self) -> TimeSource:
        return self.tree.clock

    def start_background(self, coro: Coroutine[Any, Any, Any]) -> asyncio.Task[Any]:
        """Run long work (I/O, motion) off the tick path, owned by the tree."""
        if self._tree is None:
            coro.close()
            raise TreeError(f"node {self.name!r} needs a Tree to run background work")
        return self._tree.start_task(coro, name=self.path)

    # -- life cycle -------------------------------------------------------------------
    def setup(self) -> None:
        """Prepare for ticking (allocate, connect); from uninitialized or shutdown."""
        if self.state is not _UNINIT and self.state is not _SHUTDOWN:
            raise IllegalTransition(
                f"setup of {self.name!r} while {self.state.value}: expected uninitialized "
                f"or shutdown (reset it instead)"
            )
        for c in self.children:
            c.setup()
        try:
            self.on_setup()
        except Exception as exc:
            self._fail(exc, "setup")
            self._ready = True
            self._regate()
            return
        self._ready = True
        self._regate()
        self._set(_IDLE)

    def tick(self) -> State:
        """Advance by one tick and return the new state. Never waits on I/O."""
        if self._gate is not None:  # not set up, or inputs to pull
            bad = self._before_tick()
            if bad is not None:
                return self._tick_failed(bad)
        prev = self.state
        try:
            new = self.on_tick()
        except Exception as exc:
            return self._tick_failed(exc)
        if new.__class__ is not State:
            return self._fail(TypeError(f"on_tick returned {new!r}, expected a State"), "tick")
        self.state = new
        if self._watch is not None and new is not prev:
            self._watch(self, prev, new)
        return new

    def _tick_failed(self, exc: Exception) -> State:
        for c in self.children:  # a failed node ticks them no more: halt them now
            if c.state in _ACTIVE:
                c.untick()
        return self._fail(exc, "tick")

    def _before_tick(self) -> TreeError | None:
        """Pull wired inputs; the error of a value its port's constraints refuse, if any."""
        if not self._ready:
            self._not_ready("tick")
        for key, src, out in self._pulls or ():
            self.inputs[key] = src.outputs[out]
        checks = self._gate
        return check_wired(self.inputs, checks, self.path) if type(checks) is tuple else None

    def _regate(self) -> None:
        """Keep ``_gate`` None exactly when ticking needs no check and no input pulls."""
        if not self._ready or self._pulls is None:
            self._gate = None if self._ready else True
        else:  # a tuple of the wired inputs a port constraint checks, if there are any
            ports = self.input_ports
            wired = tuple((k, p) for k, _, _ in self._pulls if (p := ports[k]).meta is not None)
            self._gate = wired or True

    def untick(self) -> None:
        """Stop background work but keep progress: active nodes pause, others go idle.

        Progress is what a later tick resumes: memory positions, a Parallel's finished
        children, Retry/Repeat counts, the time a Delay waited (a Timeout's period restarts).
        :meth:`reset` forgets it, and is the way to start over.
        """
        if not self._ready:
            self._not_ready("untick")
        try:
            self.on_untick()
        except Exception as exc:
            self._fail(exc, "untick")
            return
        prev = self.state  # _set, inlined: halting is on the tick path
        self.state = new = _PAUSED if prev in _ACTIVE or prev is _PAUSED else _IDLE
        if self._watch is not None and new is not prev:
            self._watch(self, prev, new)

    def reset(self) -> None:
        """Back to idle: outputs cleared, background work cancelled, children reset."""
        if not self._ready:
            self._not_ready("reset")
        for c in self.children:  # only what ran since its last reset: idle ones did not
            if c.state is not _IDLE:
                c.reset()
        self.error = None
        try:
            self.on_reset()
        except Exception as exc:
            self._fail(exc, "reset")
            return
        outputs = self.outputs
        if outputs:
            for key in outputs:
                outputs[key] = None
        prev = self.state  # _set, inlined: a Parallel starting over resets on the tick path
        self.state = _IDLE
        if self._watch is not None and prev is not _IDLE:
            self._watch(self, prev, _IDLE)

    def shutdown(self) -> None:
        """Release everything; the node may be set up again later."""
        for c in self.children:
            c.shutdown()
        if self.state is _SHUTDOWN or self.state is _UNINIT:
            self._ready = False
            self._regate()
            return
        try:
            self.on_shutdown()
        except Exception as exc:
            log.error("btcap.node_shutdown_failed", node=self.path, exc_info=exc)
        self._ready = False
        self._regate()
        self._set(_SHUTDOWN)

    def _set(self, new: State) -> None:
        prev = self.state
        self.state = new
        if self._watch is not None and new is not prev:
            self._watch(self, prev, new)

    def _fail(self, exc: BaseException, action: str) -> State:
        if isinstance(exc, NodeErrorWarning):  # a child's, made an error by a filter
            raise exc
        self.error = exc
        log.error(
            "btcap.node_error",
            node=self.path,
            type=type(self).__name__,
            action=action,
            exc_info=exc,
        )
        self._set(_ERROR)
        tell_error(self, exc, action)
        return _ERROR

    def _not_ready(self, action: str) -> None:
        raise IllegalTransition(
            f"{action} of {self.path!r} while {self.state.value}: call setup() first"
        )

    # -- overridables -----------------------------------------------------------------
    def on_setup(self) -> None:
        """Acquire what ticking needs."""

    def on_tick(self) -> State:
        raise NotImplementedError(f"{type(self).__name__} must implement on_tick")

    def on_untick(self) -> None:
        """Pause background work; the default unticks active children."""
        for c in self.children:
            if c.state in _ACTIVE:
                c.untick()

    def on_reset(self) -> None:
        """Forget progress; children are already reset."""

    def on_shutdown(self) -> None:
        """Release what :meth:`on_setup` acquired; children are already shut down."""

    def utility(self) -> Utility:
        """Expected cost bounds, for bids; leaves may override, composites aggregate."""
        return Utility()

    # -- actor protocol ---------------------------------------------------------------
    # The node actions as messages, from this robot's own actors only: a peer drives a
    # run it owns through the run's handle (mission control's execution messages,
    # checked against the run's origin), never by addressing nodes.
    def status(self) -> NodeStatus:
        return NodeStatus(self.state, dict(self.outputs))

    @handler(local_only=True)
    def _on_setup_msg(self, msg: Setup) -> NodeStatus:
        self.setup()
        return self.status()

    @handler(local_only=True)
    def _on_tick_msg(self, msg: Tick) -> NodeStatus:
        for key, value in msg.inputs.items():
            self.set_input(key, value)
        self.tick()
        return self.status()

    @handler(local_only=True)
    def _on_untick_msg(self, msg: Untick) -> NodeStatus:
        self.untick()
        return self.status()

    @handler(local_only=True)
    def _on_reset_msg(self, msg: Reset) -> NodeStatus:
        self.reset()
        return self.status()

    @handler(local_only=True)
    def _on_shutdown_msg(self, msg: Shutdown) -> NodeStatus:
        self.shutdown()
        return self.status()

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name!r} {self.state.value}>"


class Leaf(Node):
    """A node without children; subclass and implement :meth:`on_tick`."""

    __slots__ = ()


def declared_ports(node: Node) -> dict[str, PortMap]:
    """The node's ports by kind, as a dict (for files, CLI and docs)."""
    return {"inputs": node.input_ports, "outputs": node.output_ports, "options": type(node).OPTIONS}
