"""Trees: a root node plus data wires, a clock, background tasks and observers."""

from __future__ import annotations

import asyncio
from collections.abc import Callable, Collection, Coroutine, Iterator
from typing import TYPE_CHECKING, Any

from btcap.actors import Clock, TimeSource
from btcap.bt.blackboard import Blackboard
from btcap.bt.debug import RestartMonitor, debug_default
from btcap.bt.host import wake
from btcap.bt.node import Node, Observer
from btcap.bt.ports import PortMap, wire_problem
from btcap.bt.running import Alarm, nudge, run_tree, start_task, tick_once
from btcap.bt.state import ACTIVE, ENDED, State, TreeError
from btcap.bt.utility import Utility
from btcap.bt.wires import Wire

if TYPE_CHECKING:
    from btcap.actors import ActorSystem

__all__ = ["Subtree", "Tree", "Wire"]


class Tree:
    """A behavior tree ready to run: owns its nodes' wiring, clock and background tasks.

    ``Tree(root)`` adopts every node below ``root``; :meth:`attach` additionally spawns
    every node as an actor of an :class:`~actors.ActorSystem` so each is addressable.
    """

    def __init__(
        self,
        root: Node,
        *,
        name: str | None = None,
        clock: TimeSource | None = None,
        debug: bool | None = None,
    ) -> None:
        self.root = root
        self.name = name or root.name
        self.clock: TimeSource = clock if clock is not None else Clock()
        self.wires: list[Wire] = []
        self.system: ActorSystem | None = None
        self._observers: list[tuple[Observer, type[Node] | tuple[type[Node], ...]]] = []
        self._tasks: set[asyncio.Task[Any]] = set()
        self.blackboard: Blackboard | None = None  # entries beyond wires (XML trees)
        self.version = 0  # grows when nodes join or leave: a watcher needs no walk to see it
        self.woken = False  # a node asked to be ticked again at once (see tick_once)
        self.alarm = Alarm()  # news from outside: tick soon (nudge)
        self._monitor: RestartMonitor | None = None
        self._unmonitor: Callable[[], None] | None = None
        self._told: set[str] = set()  # nodes whose first error was a warning (bt.told)
        self._adopt(root)
        self.debug = debug_default() if debug is None else debug

    # -- debug mode -------------------------------------------------------------------
    @property
    def debug(self) -> bool:
        """Debug mode: warn about nodes caught in a restart loop (:mod:`btcap.bt.debug`);
        on by default with ``BTCAP_DEBUG`` or ``python -X dev``. Off, it costs nothing."""
        return self._monitor is not None

    @debug.setter
    def debug(self, on: bool) -> None:
        if on != self.debug:
            self._share_monitor(RestartMonitor() if on else None)

    def _share_monitor(self, monitor: RestartMonitor | None) -> None:
        """Use ``monitor`` (a Subtree's inner tree: the outer tree's; None: none)."""
        if monitor is not self._monitor:
            if self._unmonitor is not None:
                self._unmonitor()
            self._monitor = monitor
            self._unmonitor = None if monitor is None else self.observe(monitor)

    # -- structure --------------------------------------------------------------------
    def _adopt(self, node: Node) -> None:
        nodes = list(node.walk())
        for n in nodes:  # check them all before adopting any
            if n._tree is not None and n._tree is not self:
                raise TreeError(f"node {n.path!r} already belongs to tree {n._tree.name!r}")
        self.version += 1
        for n in nodes:
            n._tree = self
            n._watch = self._watch_for(n)
            if self.system is not None and not n.spawned:
                self._spawn(n)

    def _release(self, node: Node) -> None:
        self.version += 1
        gone = set(map(id, node.walk()))
        for w in [w for w in self.wires if id(w.source) in gone or id(w.target) in gone]:
            self.unwire(w)
        for n in node.walk():
            if n.spawned:
                n.system.stop(n)
            n._tree = None
            n._watch = None

    def nodes(self) -> Iterator[Node]:
        return self.root.walk()

    def find(self, path: str) -> Node:
        """The node at ``path`` (slash-separated names from the root)."""
        parts = path.split("/")
        if parts[0] != self.root.name:
            raise TreeError(f"tree {self.name!r}: no node {path!r} (root is {self.root.name!r})")
        node = self.root
        for part in parts[1:]:
            for c in node.children:
                if c.name == part:
                    node = c
                    break
            else:
                raise TreeError(
                    f"tree {self.name!r}: no node {path!r} ({node.path!r} has no child {part!r})"
                )
        return node

    def _resolve(self, node: Node | str) -> Node:
        if isinstance(node, str):
            return self.find(node)
        if node._tree is not self:
            raise TreeError(f"node {node.path!r} is not part of tree {self.name!r}")
        return node

    def insert(self, parent: Node | str, subtree: Node, index: int | None = None) -> Node:
        """Add a subtree below ``parent`` (not while the parent is running)."""
        return self._resolve(parent).add_child(subtree, index)

    def remove(self, node: Node | str) -> Node:
        """Detach a subtree (and its wires); it is shut down first."""
        n = self._resolve(node)
        if n.parent_node is None:
            raise TreeError(f"tree {self.name!r}: cannot remove the root")
        if n.state in ACTIVE:
            raise TreeError(f"cannot remove {n.path!r} while it is {n.state.value}")
        n.shutdown()
        n.parent_node.remove_child(n)
        return n

    # -- data wiring ------------------------------------------------------------------
    def wire(
        self, source: Node | str, source_port: str, target: Node | str, target_port: str
    ) -> Wire:
        """Feed ``source.outputs[source_port]`` into ``target.inputs[target_port]``.

        Type-checked now: raises TreeError naming both ends and the types.
        """
        src, dst = self._resolve(source), self._resolve(target)
        problem = wire_problem(src, source_port, dst, target_port)
        if problem:
            raise TreeError(f"wire {src.path}.{source_port} -> {dst.path}.{target_port}: {problem}")
        if any(w.target is dst and w.target_port == target_port for w in self.wires):
            raise TreeError(f"input {dst.path}.{target_port} is already wired")
        w = Wire(src, source_port, dst, target_port)
        self.wires.append(w)
        if dst._pulls is None:
            dst._pulls = []
        dst._pulls.append((target_port, src, source_port))
        dst._regate()
        return w

    def unwire(self, wire: Wire) -> None:
        self.wires.remove(wire)
        pulls = wire.target._pulls or []
        pulls.remove((wire.target_port, wire.source, wire.source_port))
        wire.target._pulls = pulls or None
        wire.target._regate()

    def validate(self, *, provided: Collection[tuple[Node, str]] = ()) -> None:
        """Check children (counts, :meth:`Node.check_children`), that every required input
        has a value, a wire or an entry, and that the :attr:`blackboard` has what it needs.

        ``provided`` lists inputs fed from outside, e.g. a :class:`Subtree`'s public inputs.
        """
        if self.blackboard is not None:
            self.blackboard.check(self.name)
        wired = {(id(n), key) for n in self.nodes() for key, _, _ in n._pulls or ()}
        wired.update((id(n), key) for n, key in provided)
        # Inputs a parent sets before ticking them (a ParallelForEach's lanes' items).
        wired.update((id(c), k) for n in self.nodes() for c, k in getattr(n, "feeds", tuple)())
        for n in self.nodes():
            cls = type(n)
            k = len(n.children)
            if k < cls.MIN_CHILDREN or (cls.MAX_CHILDREN is not None and k > cls.MAX_CHILDREN):
                most = "any" if cls.MAX_CHILDREN is None else cls.MAX_CHILDREN
                raise TreeError(
                    f"node {n.path!r} ({cls.__name__}) has {k} children; expected "
                    f"{cls.MIN_CHILDREN} to {most}"
                )
            n.check_children()
            for key, port in n.input_ports.items():
                if port.required and n.inputs.get(key) is None and (id(n), key) not in wired:
                    raise TreeError(f"node {n.path!r}: input {key!r} needs a value or a wire")

    # -- actors -----------------------------------------------------------------------
    def attach(self, system: ActorSystem) -> None:
        """Spawn every node as an actor at ``tree:<name>/<node path below the root>``."""
        if self.system is not None:
            raise TreeError(f"tree {self.name!r} is already attached to {self.system.id}")
        self.system = system
        for n in self.nodes():
            self._spawn(n)

    def _spawn(self, n: Node) -> None:
        assert self.system is not None
        if n.parent_node is None:
            self.system.spawn(n, f"tree:{self.name}")
        else:
            self.system.spawn(n, n.name, parent=n.parent_node)

    # -- running ----------------------------------------------------------------------
    def setup(self, *, provided: Collection[tuple[Node, str]] = ()) -> None:
        """Validate and set up every node; raises TreeError (and shuts down) if any failed."""
        self.validate(provided=provided)
        self.root.setup()
        failed = self.errors()
        if failed:
            self.root.shutdown()
            raise TreeError(
                f"tree {self.name!r}: setup failed: "
                + "; ".join(f"{n.path}: {type(n.error).__name__}: {n.error}" for n in failed)
            )

    def tick(self) -> State:
        """One tick of the whole tree (BehaviorTree.CPP's ``tickExactlyOnce``: a node's
        request to be ticked again at once waits for the next tick); sets the tree up."""
        root = self.root
        if not root._ready:
            self.setup()
        monitor = self._monitor
        if monitor is None:
            return root.tick()
        monitor.ticks += 1
        state = root.tick()
        if monitor.pending:
            monitor.flush()  # after the tick: an error filter fails the caller, not a node
        return state

    tick_exactly_once = tick

    def nudge(self) -> None:
        """Tick soon: news for a node came from outside (:func:`~btcap.bt.running.nudge`)."""
        nudge(self)

    def tick_once(self) -> State:
        """BehaviorTree.CPP's ``tickOnce``: a tick, repeated at once while the tree runs and
        a node asked for it (an AsyncSequence, AsyncFallback or Repeat that yielded)."""
        return tick_once(self)

    async def run(
        self,
        rate_hz: float = 10.0,
        *,
        until: Callable[[State], bool] | None = None,
        max_ticks: int | None = None,
        timeout_s: float | None = None,
        wake: bool = False,
    ) -> State:
        """Tick at ``rate_hz`` (clock time, drift-free) until a result or ``until(state)``.

        With ``wake`` a node's request to be ticked again is honoured at once, without
        waiting for the period: BehaviorTree.CPP's ``tickWhileRunning``.

        ``max_ticks`` and ``timeout_s`` (clock seconds) limit the run. A run that reaches
        a limit first halts the tree (unticks it: background work is cancelled, progress
        kept, so a later run resumes) and raises :class:`~btcap.bt.state.TreeTimeout`
        naming the limit and the nodes still running; nothing is left running.
        """
        return await run_tree(self, rate_hz, until, max_ticks, timeout_s, wake)

    def tick_until_result(self, max_ticks: int = 1_000_000) -> State:
        """Tick synchronously until succeeded/failed/error/skipped (trees with no waits)."""
        for _ in range(max_ticks):
            s = self.tick()
            if s in ENDED:
                return s
        raise TreeError(f"tree {self.name!r} gave no result within {max_ticks} ticks")

    def untick(self) -> None:
        if self.root._ready:
            self.root.untick()

    def reset(self) -> None:
        if self.root._ready:
            self.root.reset()

    async def shutdown(self) -> None:
        """Shut every node down and wait for its background work to end."""
        self.root.shutdown()
        for n in self.nodes():
            if isinstance(n, Subtree):
                await n.inner.shutdown()
        tasks = list(self._tasks)
        for t in tasks:
            t.cancel()
        if tasks:
            await asyncio.gather(*tasks, return_exceptions=True)
        if self.system is not None:
            system, self.system = self.system, None
            for n in self.nodes():
                if n._system is system:
                    system.stop(n)

    async def __aenter__(self) -> Tree:
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.shutdown()

    def start_task(
        self, coro: Coroutine[Any, Any, Any], *, name: str | None = None
    ) -> asyncio.Task[Any]:
        """Background work of a node, awaited by :meth:`shutdown` (and the system's, if any)."""
        task = start_task(self, coro, name)
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)
        return task

    # -- observing --------------------------------------------------------------------
    def observe(
        self, observer: Observer, *, only: type[Node] | tuple[type[Node], ...] = Node
    ) -> Callable[[], None]:
        """Call ``observer(node, old, new)`` on every state change of a node of the types
        ``only`` (the others' ticks do not pay for it); returns an unsubscribe."""
        entry = (observer, only)
        self._observers.append(entry)
        self._set_watch()

        def unsubscribe() -> None:
            if entry in self._observers:
                self._observers.remove(entry)
                self._set_watch()

        return unsubscribe

    def _watch_for(self, node: Node) -> Observer | None:
        """What ``node`` calls on a change: nothing, its only observer, or all of them."""
        mine = [ob for ob, only in self._observers if isinstance(node, only)]
        return None if not mine else mine[0] if len(mine) == 1 else self._notify

    def _set_watch(self) -> None:
        for n in self.nodes():
            n._watch = self._watch_for(n)

    def _notify(self, node: Node, old: State, new: State) -> None:
        for ob, only in list(self._observers):
            if isinstance(node, only):
                ob(node, old, new)

    def utility(self) -> Utility:
        return self.root.utility()

    def errors(self) -> list[Node]:
        """Nodes currently in ERROR, with their exception in ``node.error``."""
        return [n for n in self.nodes() if n.state is State.ERROR]


class Subtree(Node):
    """A whole tree used as one node, exposing some inner ports as its own.

    ``public_inputs`` maps a public input name to ``"node/path.port"`` of an inner input;
    ``public_outputs`` maps a public output name to an inner ``"node/path.port"`` output.
    """

    __slots__ = ("_in_map", "_out_map", "inner")
    MAX_CHILDREN = 0

    def __init__(
        self,
        inner: Tree,
        name: str | None = None,
        *,
        public_inputs: dict[str, str] | None = None,
        public_outputs: dict[str, str] | None = None,
        **kwargs: Any,
    ) -> None:
        self.inner = inner
        self._in_map = {k: self._split(inner, v, "input") for k, v in (public_inputs or {}).items()}
        self._out_map = {
            k: self._split(inner, v, "output") for k, v in (public_outputs or {}).items()
        }
        super().__init__(name or inner.name, **kwargs)

    @staticmethod
    def _split(inner: Tree, ref: str, kind: str) -> tuple[Node, str]:
        path, dot, port = ref.rpartition(".")
        if not dot:
            raise TreeError(
                f"subtree {inner.name!r}: {kind} {ref!r} must look like 'node/path.port'"
            )
        node = inner.find(path)
        ports = node.input_ports if kind == "input" else node.output_ports
        if port not in ports:
            raise TreeError(f"subtree {inner.name!r}: {path!r} has no {kind} {port!r}")
        return node, port

    def declare_ports(self) -> None:
        ins: PortMap = {k: n.input_ports[p] for k, (n, p) in self._in_map.items()}
        outs: PortMap = {k: n.output_ports[p] for k, (n, p) in self._out_map.items()}
        self.input_ports = ins
        self.output_ports = outs

    def on_setup(self) -> None:
        self.inner.clock = self.clock
        self.inner.alarm.outer = self._tree  # news inside: the outer tree ticks
        host = self._tree
        self.inner._share_monitor(host._monitor if isinstance(host, Tree) else None)
        self.inner.setup(provided=list(self._in_map.values()))

    def on_tick(self) -> State:
        for key, (n, p) in self._in_map.items():
            n.inputs[p] = self.inputs[key]
        inner = self.inner
        s = inner.root.tick()
        if inner.woken:  # one tree ticks: the request is the outer tree's
            inner.woken = False
            wake(self)
        for key, (n, p) in self._out_map.items():
            self.outputs[key] = n.outputs[p]
        return s

    def on_untick(self) -> None:
        self.inner.untick()

    def on_reset(self) -> None:
        self.inner.reset()

    def on_shutdown(self) -> None:
        self.inner.root.shutdown()

    def utility(self) -> Utility:
        return self.inner.utility()
