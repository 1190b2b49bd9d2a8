"""Node types by name, so tree files and the CLI can build nodes without importing code.

A registry is a plain object: :func:`default_registry` builds a fresh one holding every
built-in node plus the node packages installed under the ``btcap.nodes`` entry-point
group. It also names the types that ports carry (``"list[float]"``, ``"int | None"``), so
type-valued options such as :class:`~btcap.bt.leaves.Constant`'s ``type`` fit in a file.
"""

from __future__ import annotations

import enum
from collections.abc import Iterable, Iterator, Mapping
from importlib import metadata
from typing import Any

from btcap.bt import async_nodes, composites, decorators, foreach, leaves, read_options, switch
from btcap.bt.node import Node
from btcap.bt.scripting import nodes as scripting
from btcap.bt.spelling import did_you_mean
from btcap.bt.state import RegistryError
from btcap.bt.typenames import BUILTIN_TYPES, format_type, parse_type

# RegistryError lives in btcap.bt.state with the other tree errors; still importable here.
__all__ = [
    "ENTRY_POINT_GROUP",
    "NodeRegistry",
    "RegistryError",
    "default_registry",
]

#: The entry-point group third-party node packages register under.
ENTRY_POINT_GROUP = "btcap.nodes"

#: Prefixes of the two names a clash between btcap and a user type leaves apart:
#: ``user.Wait`` is a user's class registered as ``Wait`` while btcap's own ``Wait``
#: keeps the plain name in YAML, JSON and Python; ``btcap.Log`` is btcap's own ``Log``
#: in BehaviorTree.CPP XML, where plain names never mean btcap-only types.
USER_PREFIX = "user."
BTCAP_PREFIX = "btcap."

#: Names handled by the tree-file format itself, never by a registry entry.
RESERVED = frozenset({"Subtree"})

#: Node types btcap no longer has, and what a file should say instead.
REMOVED = {
    "FallbackWithMemory": "it was removed in btcap 0.2; use Fallback, which now resumes "
    "at the running child as FallbackWithMemory did (ReactiveFallback re-ticks from the "
    "first child every tick)",
}

#: Exported node classes that cannot be built from a file: they need Python callables
#: (Action, Condition) or are abstract bases (Decorator, Remap).
_NOT_FROM_FILES = frozenset({"Action", "Condition", "Decorator", "Remap"})


def _builtin_nodes() -> list[type[Node]]:
    """Every node class the core exports that a file can build (no callables needed)."""
    out: list[type[Node]] = []
    for module in (
        composites,
        async_nodes,
        switch,
        foreach,
        decorators,
        leaves,
        scripting,
        read_options,
    ):
        for name in module.__all__:
            obj = getattr(module, name)
            if isinstance(obj, type) and issubclass(obj, Node) and name not in _NOT_FROM_FILES:
                out.append(obj)
    return out


class NodeRegistry:
    """Maps type names used in files to node classes, and type names to port types."""

    def __init__(
        self,
        nodes: Iterable[type[Node]] = (),
        *,
        types: Mapping[str, Any] | None = None,
    ) -> None:
        self._nodes: dict[str, type[Node]] = {}
        self._names: dict[type[Node], str] = {}
        self._types: dict[str, Any] = dict(BUILTIN_TYPES)
        #: name -> ``user.name`` for user types named like a btcap built-in.
        self._shadow: dict[str, str] = {}
        #: Names BehaviorTree.CPP scripts read as numbers (its ``registerScriptingEnum``).
        self.script_enums: dict[str, int] = {}
        self._builtins = frozenset(_builtin_nodes())
        for cls in nodes:
            self.register(cls)
        for name, tp in (types or {}).items():
            self.register_type(name, tp)

    # -- node types -------------------------------------------------------------------
    def register(self, cls: type[Node], name: str | None = None) -> type[Node]:
        """Add a node class under ``name`` (default: its class name); returns ``cls``.

        Usable as a decorator. A name may be taken only once, so a file never silently
        builds a different class than its author meant; the one exception is a class
        named like a btcap built-in (``Wait``, ``Log``): it is registered as
        ``user.Wait``, YAML and Python keep meaning btcap's ``Wait`` by the plain name,
        and BehaviorTree.CPP XML, where btcap's own nodes never capture an element,
        means the user's (:meth:`xml_type`).
        """
        if not (isinstance(cls, type) and issubclass(cls, Node)):
            raise RegistryError(f"cannot register {cls!r}: expected a Node subclass")
        key = cls.__name__ if name is None else name
        if not key or not all(part.isidentifier() for part in key.split(".")):
            raise RegistryError(
                f"cannot register {cls.__qualname__} as {key!r}: expected an identifier "
                f"(dots allowed, e.g. 'acme.Grasp')"
            )
        if key in RESERVED:
            raise RegistryError(
                f"cannot register {cls.__qualname__} as {key!r}: the name is reserved "
                f"for the tree-file format"
            )
        old = self._nodes.get(key)
        if old is not None and old in self._builtins and cls not in self._builtins:
            if key in self._shadow:
                old = self._nodes[self._shadow[key]]
            else:
                self._shadow[key] = USER_PREFIX + key
                return self.register(cls, USER_PREFIX + key)
        if old is not None:
            raise RegistryError(
                f"node type {key!r} is already registered "
                f"({old.__module__}.{old.__qualname__}); cannot add "
                f"{cls.__module__}.{cls.__qualname__} under the same name"
            )
        self._nodes[key] = cls
        self._names.setdefault(cls, key)
        return cls

    def get(self, name: str) -> type[Node]:
        """The node class registered as ``name``; the error suggests close names."""
        try:
            return self._nodes[name]
        except KeyError:
            pass
        if name in REMOVED:
            raise RegistryError(f"node type {name!r}: {REMOVED[name]}")
        hint = " (Subtree is built from the file's 'subtrees')" if name in RESERVED else ""
        raise RegistryError(
            f"unknown node type {name!r}{did_you_mean(name, self._nodes) or hint}; "
            f"'btcap tree nodes' lists the known types"
        )

    def is_builtin(self, name: str) -> bool:
        """Whether ``name`` is one of btcap's own node types (not a user's)."""
        return self._nodes.get(name) in self._builtins

    def xml_type(self, name: str) -> str | None:
        """The registered name a BehaviorTree.CPP XML element ``name`` builds, or None.

        XML means BehaviorTree.CPP's names: a user type (``Wait`` -> ``user.Wait`` if
        it shares a btcap built-in's name), never a btcap-only built-in unless spelt
        ``btcap.Log``. BehaviorTree.CPP's own node names are mapped before this.
        """
        if name in self._shadow:
            return self._shadow[name]
        if name.startswith(BTCAP_PREFIX):
            plain = name.removeprefix(BTCAP_PREFIX)
            return plain if self.is_builtin(plain) else None
        if name in self._nodes and not self.is_builtin(name):
            return name
        return None

    def copy(self) -> NodeRegistry:
        """A registry with the same entries, to add types to without touching this one."""
        out = NodeRegistry()
        out._nodes = dict(self._nodes)
        out._names = dict(self._names)
        out._types = dict(self._types)
        out._shadow = dict(self._shadow)
        out.script_enums = dict(self.script_enums)
        return out

    def register_enum(self, values: type[enum.Enum] | Mapping[str, int]) -> None:
        """Let BehaviorTree.CPP scripts use these names as numbers: an IntEnum's members,
        or a mapping of name to value (BehaviorTree.CPP's ``registerScriptingEnum``)."""
        items = (
            {m.name: m.value for m in values}
            if isinstance(values, type) and issubclass(values, enum.Enum)
            else dict(values)
        )
        for name, value in items.items():
            if not name.isidentifier() or isinstance(value, bool) or not isinstance(value, int):
                raise RegistryError(
                    f"script enum {name!r}={value!r}: expected an identifier and an integer"
                )
            old = self.script_enums.setdefault(name, value)
            if old != value:
                raise RegistryError(f"script enum {name!r} is already {old}, not {value}")

    def name_of(self, cls: type[Node]) -> str:
        """The name ``cls`` was registered under (first one, if several)."""
        try:
            return self._names[cls]
        except KeyError:
            raise RegistryError(
                f"node class {cls.__module__}.{cls.__qualname__} is not registered; "
                f"register it to write it to a file"
            ) from None

    def names(self) -> list[str]:
        return sorted(self._nodes)

    def classes(self) -> set[type[Node]]:
        """Every registered class, whatever its names."""
        return set(self._names)

    def __contains__(self, name: object) -> bool:
        return name in self._nodes

    def __iter__(self) -> Iterator[str]:
        return iter(sorted(self._nodes))

    def __len__(self) -> int:
        return len(self._nodes)

    def items(self) -> list[tuple[str, type[Node]]]:
        return sorted(self._nodes.items())

    # -- plugins ----------------------------------------------------------------------
    def load_entry_points(self, group: str = ENTRY_POINT_GROUP) -> list[str]:
        """Register the node packages installed under ``group``; returns the names added.

        Each entry point names a Node subclass, or a callable returning an iterable of
        them. A broken one raises :class:`RegistryError` naming the entry point, so a bad
        plugin is found at start-up rather than when a file happens to use it.
        """
        added: list[str] = []
        for ep in sorted(metadata.entry_points(group=group), key=lambda e: e.name):
            where = f"node plugin {ep.name!r} ({ep.value}) in entry-point group {group!r}"
            try:
                obj = ep.load()
            except Exception as exc:
                raise RegistryError(f"{where} failed to load: {type(exc).__name__}: {exc}") from exc
            for cls in self._plugin_classes(obj, where):
                try:
                    self.register(cls)
                except RegistryError as exc:
                    raise RegistryError(f"{where}: {exc}") from None
                added.append(self.name_of(cls))
        return added

    @staticmethod
    def _plugin_classes(obj: object, where: str) -> list[type[Node]]:
        if isinstance(obj, type):
            if issubclass(obj, Node):
                return [obj]
            raise RegistryError(f"{where}: {obj.__qualname__} is not a Node subclass")
        if not callable(obj):
            raise RegistryError(
                f"{where}: expected a Node subclass or a callable returning Node subclasses, "
                f"got {type(obj).__qualname__}"
            )
        try:
            produced = list(obj())
        except Exception as exc:
            raise RegistryError(f"{where}: calling it failed: {type(exc).__name__}: {exc}") from exc
        bad = [c for c in produced if not (isinstance(c, type) and issubclass(c, Node))]
        if bad:
            raise RegistryError(f"{where}: returned {bad[0]!r}; expected only Node subclasses")
        return produced

    # -- type names -------------------------------------------------------------------
    def register_type(self, name: str, tp: Any) -> None:
        """Let files name ``tp`` (e.g. a msgspec Struct of a node package) as ``name``."""
        if not all(part.isidentifier() for part in name.split(".")):
            raise RegistryError(f"type name {name!r}: expected an identifier")
        old = self._types.get(name, tp)
        if old is not tp:
            raise RegistryError(f"type name {name!r} is already taken by {old!r}")
        self._types[name] = tp

    def parse_type(self, text: str) -> Any:
        """Turn ``"dict[str, list[float]] | None"`` into the type; no eval involved."""
        return parse_type(text, self._types)

    def format_type(self, tp: Any) -> str:
        """The inverse of :meth:`parse_type`; raises RegistryError for unnamed types."""
        return format_type(tp, self._types)


def default_registry(*, plugins: bool = True) -> NodeRegistry:
    """A new registry with every built-in node and, if ``plugins``, the installed packages.

    Built fresh on each call (no module-level state), so callers may add their own
    types without affecting anyone else.
    """
    reg = NodeRegistry(_builtin_nodes())
    if plugins:
        reg.load_entry_points()
    return reg
