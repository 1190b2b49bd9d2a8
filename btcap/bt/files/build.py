"""Building Trees from a checked tree file, reporting every problem with node path and field.

Building goes on past a problem (a bad node is skipped, its subtree still built): one
load reports all the mistakes in a file. Inputs a parent feeds (``feeds``) need no wire."""

from __future__ import annotations

import dataclasses
import typing
from pathlib import Path
from typing import Any

from btcap.bt.files.board import Boards
from btcap.bt.files.parse import read_tree_file
from btcap.bt.files.schema import (
    FileInfo,
    NodeSpec,
    PublicSpec,
    TreeFile,
    TreeFileError,
    WireSpec,
    file_info,
    is_type_option,
    literal,
    set_file_info,
)
from btcap.bt.node import Node
from btcap.bt.ports import check_port, type_name
from btcap.bt.registry import NodeRegistry, RegistryError
from btcap.bt.spelling import did_you_mean
from btcap.bt.state import TreeError
from btcap.bt.tree import Subtree, Tree

if typing.TYPE_CHECKING:
    from btcap.actors import TimeSource

__all__ = ["MAX_NODES", "Builder"]

#: Nodes one file may build, every Subtree use counted as the copy it is.
MAX_NODES = 100_000


def _split_ref(ref: str) -> tuple[str, str] | None:
    path, dot, port = ref.rpartition(".")
    if not dot or not path or not port:
        return None
    return path, port


class Builder:
    """Builds one file's trees, collecting every problem instead of stopping at the first."""

    def __init__(
        self,
        spec: TreeFile,
        where: str,
        registry: NodeRegistry,
        base: Path | None,
        stack: tuple[Path, ...],
        cache: dict[Path, TreeFile],
        boards: Boards | None = None,
    ) -> None:
        self.spec = spec
        self.boards = boards  # an XML file's blackboard entries
        self.where = where
        self.registry = registry
        self.base = base
        self.stack = stack
        self.cache = cache
        self.problems: list[str] = []
        self._checked: dict[str, bool] = {}
        self._building: list[str] = []
        self._bad_inputs: set[tuple[str, str, str]] = set()  # (ctx, path, input) reported

    def fail(self, msg: str) -> None:
        self.problems.append(f"{self.where}: {msg}")

    # -- trees ------------------------------------------------------------------------
    def build_main(self, clock: TimeSource | None) -> Tree:
        total, what = self._expanded()
        if total > MAX_NODES:
            raise TreeFileError(
                [
                    f"{self.where}: {what} expands to {total} nodes (each Subtree use "
                    f"is a copy of its subtree); btcap builds at most {MAX_NODES}"
                ]
            )
        for name in self.spec.subtrees:
            self._check_subtree(name)
        spec = self.spec
        tree = self._tree(spec.root, spec.wires, spec.public, spec.name, "", clock)
        if self.problems or tree is None:
            raise TreeFileError(self.problems)
        set_file_info(tree, FileInfo(spec.description, spec.public))
        return tree

    def _tree(
        self,
        root_spec: NodeSpec,
        wires: list[WireSpec],
        public: PublicSpec | None,
        name: str | None,
        ctx: str,
        clock: TimeSource | None = None,
    ) -> Tree | None:
        failed: list[str] = []
        if self.boards is not None:
            self.boards.enter(name or "")
        root = self._node(root_spec, None, ctx, failed)
        tree = None if root is None else Tree(root, name=name, clock=clock)
        wired = self.boards.leave(tree, self.fail, ctx) if self.boards is not None else set()
        if tree is None:
            return None
        wired |= {(c.path, k) for n in tree.nodes() for c, k in getattr(n, "feeds", tuple)()}
        for i, w in enumerate(wires):
            self._wire(tree, i, w, ctx, failed, wired)
        public_in: set[tuple[str, str]] = set()
        if public is not None:
            public_in = self._check_public(tree, public, ctx, failed)
        for n in tree.nodes():
            if _under(n.path, failed):
                continue
            for key, port in n.input_ports.items():
                if (
                    port.required
                    and n.inputs.get(key) is None
                    and (n.path, key) not in wired
                    and (n.path, key) not in public_in
                    and (ctx, n.path, key) not in self._bad_inputs
                ):
                    self.fail(
                        f"{ctx}node {n.path!r} input {key!r}: required "
                        f"({type_name(port.type)}) but has no value, no wire and is not public"
                    )
        return tree

    def _wire(
        self,
        tree: Tree,
        i: int,
        w: WireSpec,
        ctx: str,
        failed: list[str],
        wired: set[tuple[str, str]],
    ) -> None:
        loc = f"{ctx}wires[{i}] ({w.source} -> {w.target})"
        src, dst = _split_ref(w.source), _split_ref(w.target)
        for field, ref, value in (("from", src, w.source), ("to", dst, w.target)):
            if ref is None:
                self.fail(f"{loc} field {field!r}: {value!r} is not 'node/path.port'")
        if src is None or dst is None or _under(src[0], failed) or _under(dst[0], failed):
            return
        wired.add(dst)  # even if it fails below: a bad wire is one problem, not two
        try:
            tree.wire(src[0], src[1], dst[0], dst[1])
        except TreeError as exc:
            self.fail(f"{loc}: {exc}")

    def _check_public(
        self, tree: Tree, public: PublicSpec, ctx: str, failed: list[str]
    ) -> set[tuple[str, str]]:
        out: set[tuple[str, str]] = set()
        for kind, refs in (("inputs", public.inputs), ("outputs", public.outputs)):
            for key, ref in refs.items():
                loc = f"{ctx}field 'public.{kind}.{key}'"
                if not key.isidentifier():
                    self.fail(f"{loc}: public name {key!r} is not an identifier")
                split = _split_ref(ref)
                if split is None:
                    self.fail(f"{loc}: {ref!r} is not 'node/path.port'")
                    continue
                if _under(split[0], failed):
                    continue
                try:
                    node = tree.find(split[0])
                except TreeError as exc:
                    self.fail(f"{loc}: {exc}")
                    continue
                ports = node.input_ports if kind == "inputs" else node.output_ports
                if split[1] not in ports:
                    self.fail(
                        f"{loc}: node {split[0]!r} has no {kind[:-1]} {split[1]!r} "
                        f"({kind}: {', '.join(ports) or 'none'})"
                    )
                    continue
                if kind == "inputs":
                    out.add(split)
        return out

    # -- subtrees ---------------------------------------------------------------------
    def _expanded(self) -> tuple[int, str]:
        """The most nodes the main tree or a subtree (each is built, used or not) builds
        to, and which: subtrees nested in subtrees multiply. A cycle counts once (it is
        reported when building)."""
        sizes: dict[str, int] = {}

        def size(spec: NodeSpec, active: tuple[str, ...]) -> int:
            n = 1 + sum(size(c, active) for c in spec.children)
            ref = spec.options.get("tree") if spec.type == "Subtree" else None
            if isinstance(ref, str) and ref in self.spec.subtrees and ref not in active:
                if ref not in sizes:
                    root = self.spec.subtrees[ref].root
                    sizes[ref] = size(root, (*active, ref)) if root is not None else 1
                n += sizes[ref]
            return n

        most = (size(self.spec.root, ()), "the tree")
        for name, sub in self.spec.subtrees.items():
            if name not in sizes:
                sizes[name] = size(sub.root, (name,)) if sub.root is not None else 1
        return max([most, *((n, f"subtree {name!r}") for name, n in sizes.items())])

    def _check_subtree(self, name: str) -> bool:
        """Build a definition once to report its problems; cached, cycles reported."""
        if name in self._checked:
            return self._checked[name]
        if name in self._building:
            return False
        self._building.append(name)
        before = len(self.problems)
        held = self.boards.hold() if self.boards is not None else None  # checked alone
        ok = self._build_subtree(name) is not None and len(self.problems) == before
        if self.boards is not None:
            self.boards.next = held
        self._building.pop()
        self._checked[name] = ok
        return ok

    def _instance(self, name: str) -> tuple[Tree, PublicSpec] | None:
        """A fresh copy of a (checked) subtree definition for one Subtree node."""
        if not self._check_subtree(name):
            return None
        saved, self.problems = self.problems, []
        try:
            return self._build_subtree(name)
        finally:
            self.problems = saved

    def _build_subtree(self, name: str) -> tuple[Tree, PublicSpec] | None:
        sub = self.spec.subtrees[name]
        ctx = f"subtree {name!r} "
        if sub.file is not None:
            return self._file_subtree(name, sub.file, ctx)
        assert sub.root is not None
        tree = self._tree(sub.root, sub.wires, sub.public, name, ctx)
        if tree is None:
            return None
        set_file_info(tree, FileInfo(sub.description, sub.public))
        return tree, sub.public or PublicSpec()

    def _file_subtree(self, name: str, ref: str, ctx: str) -> tuple[Tree, PublicSpec] | None:
        path = Path(ref)
        if not path.is_absolute():
            path = (self.base or Path.cwd()) / path
        resolved = path.resolve()
        if resolved in self.stack:
            chain = " -> ".join(str(p) for p in (*self.stack, resolved))
            self.fail(f"{ctx}field 'file': the file includes itself ({chain})")
            return None
        try:
            spec = self.cache.get(resolved) or read_tree_file(path)
            self.cache[resolved] = spec
            inner = Builder(
                spec, str(path), self.registry, path.parent, (*self.stack, resolved), self.cache
            )
            tree = inner.build_main(None)
        except TreeFileError as exc:
            for p in exc.problems:
                self.fail(f"{ctx}(file {ref}): {p}")
            return None
        tree.name = name
        info = file_info(tree)
        set_file_info(tree, dataclasses.replace(info, source=resolved))
        return tree, info.public or PublicSpec()

    # -- nodes ------------------------------------------------------------------------
    def _node(self, spec: NodeSpec, parent: str | None, ctx: str, failed: list[str]) -> Node | None:
        name = spec.name
        if name is None:
            tree_ref = spec.options.get("tree")
            name = tree_ref if spec.type == "Subtree" and isinstance(tree_ref, str) else spec.type
            name = name.rsplit(".", 1)[-1]  # user.Wait, acme.Grasp: a name has no dots
        path = name if parent is None else f"{parent}/{name}"
        loc = f"{ctx}node {path!r}"
        if not name or "/" in name or "." in name:
            self.fail(f"{loc} field 'name': expected a non-empty name without '/' or '.'")
            failed.append(path)
            return None
        if spec.type == "Subtree":
            if self.boards is not None:
                self.boards.subtree(path)
            node = self._subtree_node(spec, name, loc)
        else:
            node = self._plain_node(spec, name, loc)
        if node is None:
            failed.append(path)
            return None
        self._inputs(node, spec, loc, (ctx, path))
        self._children(node, spec, path, loc, ctx, failed)
        return node

    def _plain_node(self, spec: NodeSpec, name: str, loc: str) -> Node | None:
        try:
            cls = self.registry.get(spec.type)
        except RegistryError as exc:
            self.fail(f"{loc} field 'type': {exc}")
            return None
        ok = True
        options: dict[str, Any] = {}
        declared = cls.OPTIONS
        for key, value in spec.options.items():
            where = f"{self.where}: {loc} option {key!r}"
            port = declared.get(key)
            if port is None:
                self.fail(
                    f"{loc} option {key!r}: unknown option of {spec.type}"
                    f"{did_you_mean(key, declared)}; options: {', '.join(declared) or 'none'}"
                )
                ok = False
                continue
            if is_type_option(cls, key, port):
                if not isinstance(value, str):
                    self.fail(
                        f"{loc} option {key!r}: expected a type name such as 'float' or "
                        f"'list[int]', got {value!r}"
                    )
                    ok = False
                    continue
                try:
                    value = self.registry.parse_type(value)
                except RegistryError as exc:
                    self.fail(f"{loc} option {key!r}: {exc}")
                    ok = False
                    continue
            try:
                options[key] = check_port(literal(value), port, where)
            except TreeError as exc:
                self.problems.append(str(exc))
                ok = False
        for key, port in declared.items():
            if port.required and key not in spec.options:
                self.fail(f"{loc} option {key!r}: required ({type_name(port.type)}) but missing")
                ok = False
        if not ok:
            return None
        try:
            return cls(name, **options)
        except Exception as exc:
            self.fail(f"{loc} field 'options': {_strip_self(str(exc), name, spec.type)}")
            return None

    def _subtree_node(self, spec: NodeSpec, name: str, loc: str) -> Node | None:
        extra = sorted(set(spec.options) - {"tree"})
        if extra:
            self.fail(
                f"{loc} option {extra[0]!r}: unknown option of Subtree; options: tree "
                f"(the name of an entry in 'subtrees')"
            )
            return None
        ref = spec.options.get("tree")
        if not isinstance(ref, str):
            self.fail(
                f"{loc} option 'tree': expected the name of an entry in 'subtrees', got {ref!r}"
            )
            return None
        if ref not in self.spec.subtrees:
            known = ", ".join(self.spec.subtrees) or "none"
            self.fail(
                f"{loc} option 'tree': unknown subtree {ref!r}"
                f"{did_you_mean(ref, self.spec.subtrees)}; subtrees: {known}"
            )
            return None
        if ref in self._building:
            chain = " -> ".join([*self._building[self._building.index(ref) :], ref])
            self.fail(f"{loc} option 'tree': subtree {ref!r} uses itself ({chain})")
            return None
        made = self._instance(ref)
        if made is None:
            return None  # the definition's own problems are reported once
        inner, public = made
        try:
            return Subtree(inner, name, public_inputs=public.inputs, public_outputs=public.outputs)
        except TreeError as exc:
            self.fail(f"{loc} option 'tree': {exc}")
            return None

    def _inputs(self, node: Node, spec: NodeSpec, loc: str, at: tuple[str, str]) -> None:
        for key, value in spec.inputs.items():
            port = node.input_ports.get(key)
            if port is None:
                self.fail(
                    f"{loc} input {key!r}: {spec.type} has no such input"
                    f"{did_you_mean(key, node.input_ports)}; inputs: "
                    f"{', '.join(node.input_ports) or 'none'}"
                )
                continue
            try:
                where = f"{self.where}: {loc} input {key!r}"
                node.set_input(key, check_port(literal(value), port, where))
            except TreeError as exc:
                self.problems.append(str(exc))
                self._bad_inputs.add((*at, key))

    def _children(
        self, node: Node, spec: NodeSpec, path: str, loc: str, ctx: str, failed: list[str]
    ) -> None:
        cls = type(node)
        n = len(spec.children)
        lo, hi = cls.MIN_CHILDREN, cls.MAX_CHILDREN
        if n < lo or (hi is not None and n > hi):
            want = (
                f"exactly {lo}" if lo == hi else f"{lo} to {'any number of' if hi is None else hi}"
            )
            noun = "child" if lo == hi == 1 else "children"
            self.fail(f"{loc} field 'children': {spec.type} takes {want} {noun}, got {n}")
            failed.append(path)
        attach = path not in failed
        seen: set[str] = set()
        for i, child_spec in enumerate(spec.children):
            child = self._node(child_spec, path, ctx, failed)
            if child is None or not attach:
                continue  # built anyway, to report the problems inside it
            if child.name in seen:
                self.fail(
                    f"{loc} field 'children[{i}]': a second child named {child.name!r}; "
                    f"sibling names must be unique (give it a 'name')"
                )
                continue
            seen.add(child.name)
            node.add_child(child)
        if attach:
            try:
                node.check_children()
            except TreeError as exc:
                self.fail(f"{loc}: {_strip_self(str(exc), node.name, spec.type)}")


def _under(path: str, failed: list[str]) -> bool:
    return any(path == f or path.startswith(f + "/") for f in failed)


def _strip_self(msg: str, name: str, tname: str) -> str:
    """Drop the node's own name from a core error, the path already says which node."""
    for prefix in (f"node {name!r} ({tname}): ", f"node {name!r} ", f"{tname} {name!r}: "):
        if msg.startswith(prefix):
            return msg[len(prefix) :]
    return msg
