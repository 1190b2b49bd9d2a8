"""Tree files: one versioned schema, in YAML or JSON, loaded into Trees and written back.

A file holds a root node (type, name, options, constant inputs, children), the data
wires between node ports, named subtrees (inline or in other files) usable as
``{type: Subtree, options: {tree: NAME}}`` nodes, and the ports it makes public when
it is itself used as a subtree::

    btcap: 1
    name: patrol
    root:
      type: Sequence
      name: root
      children:
        - {type: Constant, name: goal, options: {value: [1.0, 2.0], type: "list[float]"}}
        - {type: Subtree, name: go, options: {tree: goto}}
    wires:
      - {from: root/goal.value, to: root/go.goal}
    subtrees:
      goto:
        root: {type: Log, name: say, options: {message: moving}}
        public: {inputs: {goal: say.value}}

Every problem is reported with the file, the node path and the field; loading checks
everything it can before giving up, so one run shows all the mistakes in a file.
"""

from __future__ import annotations

import dataclasses
import difflib
import os
import re
import typing
from collections.abc import Iterable
from pathlib import Path
from typing import Any, Literal

import msgspec
import msgspec.json
import msgspec.yaml
import yaml

from btcap.bt.node import Node
from btcap.bt.ports import Port, check_value, type_name
from btcap.bt.registry import NodeRegistry, RegistryError, default_registry
from btcap.bt.state import TreeError
from btcap.bt.tree import Subtree, Tree

if typing.TYPE_CHECKING:
    from btcap.actors import TimeSource

__all__ = [
    "SCHEMA_VERSION",
    "FileInfo",
    "NodeSpec",
    "PublicSpec",
    "SubtreeSpec",
    "TreeFile",
    "TreeFileError",
    "WireSpec",
    "dump_tree",
    "dumps_tree",
    "file_info",
    "load_tree",
    "loads_tree",
    "read_tree_file",
    "save_tree",
    "validate_file",
]

#: The schema version this btcap reads and writes (the ``btcap:`` key of every file).
SCHEMA_VERSION = 1

Format = Literal["yaml", "json"]
_SUFFIXES: dict[str, Format] = {".yaml": "yaml", ".yml": "yaml", ".json": "json"}
_INFO_ATTR = "file_info"


class TreeFileError(TreeError):
    """A tree file is invalid; ``problems`` lists every finding, each starting with the file."""

    def __init__(self, problems: Iterable[str]) -> None:
        self.problems = list(problems)
        super().__init__("\n".join(self.problems))


# -- schema ---------------------------------------------------------------------------
class NodeSpec(msgspec.Struct, forbid_unknown_fields=True, omit_defaults=True, kw_only=True):
    """One node: registered type, name (default: the type), options, inputs, children."""

    type: str
    name: str | None = None
    options: dict[str, Any] = {}
    inputs: dict[str, Any] = {}
    children: list[NodeSpec] = []


class WireSpec(msgspec.Struct, forbid_unknown_fields=True):
    """``from: node/path.output`` feeds ``to: node/path.input`` (paths start at the root)."""

    source: str = msgspec.field(name="from")
    target: str = msgspec.field(name="to")


class PublicSpec(msgspec.Struct, forbid_unknown_fields=True, omit_defaults=True, kw_only=True):
    """Ports a tree exposes when used as a subtree: public name -> ``node/path.port``."""

    inputs: dict[str, str] = {}
    outputs: dict[str, str] = {}


class SubtreeSpec(msgspec.Struct, forbid_unknown_fields=True, omit_defaults=True, kw_only=True):
    """A named inner tree: inline (``root``, ``wires``, ``public``) or ``file: other.yaml``.

    A file path is relative to the file that names it; the other file's own ``public``
    section then says which ports the subtree exposes.
    """

    file: str | None = None
    description: str = ""
    root: NodeSpec | None = None
    wires: list[WireSpec] = []
    public: PublicSpec | None = None


class TreeFile(msgspec.Struct, forbid_unknown_fields=True, omit_defaults=True, kw_only=True):
    """A whole tree file (schema version :data:`SCHEMA_VERSION`)."""

    btcap: int
    name: str | None = None
    description: str = ""
    root: NodeSpec
    wires: list[WireSpec] = []
    subtrees: dict[str, SubtreeSpec] = {}
    public: PublicSpec | None = None


_STRUCT_FIELDS: dict[str, tuple[str, ...]] = {
    "file": ("btcap", "name", "description", "root", "wires", "subtrees", "public"),
    "subtree": ("file", "description", "root", "wires", "public"),
    "node": ("type", "name", "options", "inputs", "children"),
    "wire": ("from", "to"),
    "public": ("inputs", "outputs"),
}


@dataclasses.dataclass(frozen=True)
class FileInfo:
    """What a file says about a tree beyond its nodes; kept on the Tree for saving."""

    description: str = ""
    public: PublicSpec | None = None
    #: The file a subtree came from (it is saved as a reference to that file again).
    source: Path | None = None


def file_info(tree: Tree) -> FileInfo:
    """The :class:`FileInfo` a loaded tree carries (empty for trees built in code)."""
    info = getattr(tree, _INFO_ATTR, None)
    return info if isinstance(info, FileInfo) else FileInfo()


def _set_info(tree: Tree, info: FileInfo) -> None:
    setattr(tree, _INFO_ATTR, info)


# -- decoding -------------------------------------------------------------------------
def _format_of(path: Path) -> Format:
    fmt = _SUFFIXES.get(path.suffix.lower())
    if fmt is None:
        raise TreeFileError(
            [
                f"{path}: unknown file type {path.suffix or '(none)'!r}; "
                f"expected .yaml, .yml or .json"
            ]
        )
    return fmt


def _decode(text: bytes | str, fmt: Format, where: str) -> Any:
    try:
        if fmt == "json":
            return msgspec.json.decode(text)
        raw = msgspec.yaml.decode(text)
        dups = _yaml_duplicates(text)
    except (msgspec.DecodeError, yaml.YAMLError) as exc:
        raise TreeFileError(
            [f"{where}: malformed {fmt.upper()}: {_decode_detail(str(exc), text)}"]
        ) from None
    if dups:
        raise TreeFileError(f"{where}: {d}" for d in dups)
    return raw


_Loader: type[yaml.SafeLoader] = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def _yaml_duplicates(text: bytes | str) -> list[str]:
    """YAML silently keeps the last of two equal keys; a tree file must not."""
    out: list[tuple[int, str]] = []
    stack = [yaml.compose(text, Loader=_Loader)]
    while stack:
        node = stack.pop()
        if isinstance(node, yaml.MappingNode):
            seen: set[str] = set()
            for key, value in node.value:
                if isinstance(key, yaml.ScalarNode):
                    if key.value in seen:
                        line = key.start_mark.line + 1
                        out.append((line, f"line {line}: duplicate key {key.value!r}"))
                    seen.add(key.value)
                stack.append(value)
        elif isinstance(node, yaml.SequenceNode):
            stack.extend(node.value)
    return [f"{msg} (YAML would silently keep only the last one)" for _, msg in sorted(out)]


def _decode_detail(msg: str, text: bytes | str) -> str:
    """Make parser messages point at a line: YAML's marks, JSON's byte offsets."""
    msg = msg.replace('in "<unicode string>", ', "").replace('in "<byte string>", ', "")
    msg = msg.removeprefix("JSON is malformed: ")
    msg = "; ".join(part.strip() for part in msg.splitlines() if part.strip())
    m = re.search(r"\(byte (\d+)\)", msg)
    if m:
        data = text.encode() if isinstance(text, str) else text
        offset = int(m.group(1))
        line = data.count(b"\n", 0, offset) + 1
        col = offset - (data.rfind(b"\n", 0, offset) + 1) + 1
        msg = msg.replace(m.group(0), f"(line {line}, column {col})")
    return msg


def _parse(raw: Any, where: str) -> TreeFile:
    """Check the version, then convert to :class:`TreeFile`, translating error paths."""
    if raw is None:
        raise TreeFileError(
            [f"{where}: the file is empty; expected a btcap tree (btcap: 1, root: ...)"]
        )
    if not isinstance(raw, dict):
        raise TreeFileError(
            [f"{where}: top level: expected a mapping with btcap, root, ..., got {_kind(raw)}"]
        )
    version = raw.get("btcap")
    if "btcap" not in raw:
        raise TreeFileError(
            [f"{where}: field 'btcap': missing; a tree file starts with 'btcap: {SCHEMA_VERSION}'"]
        )
    if isinstance(version, bool) or version != SCHEMA_VERSION:
        raise TreeFileError(
            [
                f"{where}: field 'btcap': unsupported schema version {version!r}; this btcap "
                f"reads version {SCHEMA_VERSION}"
            ]
        )
    problems: list[str] = []
    subtrees: dict[str, SubtreeSpec] = {}
    raw_subs = raw.get("subtrees")
    if isinstance(raw_subs, dict):
        for key, value in raw_subs.items():
            if not isinstance(key, str):
                continue  # reported by the whole-file conversion below
            label = f"subtree {key!r} "
            try:
                sub = msgspec.convert(value, SubtreeSpec)
            except msgspec.ValidationError as exc:
                problems.append(_translate(str(exc), value, "subtree", where, label))
                continue
            if (sub.file is None) == (sub.root is None):
                problems.append(
                    f"{where}: {label}field 'root': give either 'root' (an inline tree) or "
                    f"'file' (a path to a tree file), not {'both' if sub.file else 'neither'}"
                )
            elif sub.file is not None and (sub.wires or sub.public or sub.description):
                problems.append(
                    f"{where}: {label}field 'file': a subtree from a file takes no wires, "
                    f"public or description here (the other file has its own)"
                )
            else:
                subtrees[key] = sub
        raw = {**raw, "subtrees": {k: {"file": "-"} for k in raw_subs}}
    try:
        spec = msgspec.convert(raw, TreeFile)
    except msgspec.ValidationError as exc:
        problems.append(_translate(str(exc), raw, "file", where, ""))
        raise TreeFileError(problems) from None
    if problems:
        raise TreeFileError(problems)
    return msgspec.structs.replace(spec, subtrees=subtrees)


def _kind(value: Any) -> str:
    for cls, word in ((dict, "a mapping"), (list, "a list"), (str, "a string")):
        if isinstance(value, cls):
            return word
    return type(value).__name__


_STEP = re.compile(r"\.([^.\[]+)|\[(\d+|\.\.\.)\]")


def _translate(msg: str, raw: Any, kind: str, where: str, label: str) -> str:
    """Turn ``Expected `int`, got `str` - at `$.root.children[1].name``` into a node path."""
    text, _, loc = msg.partition(" - at `")
    loc = loc.rstrip("`")
    is_key = loc.startswith("key` in `")
    if is_key:
        loc = loc[len("key` in `") :]
    steps: list[str | int] = []
    for m in _STEP.finditer(loc.removeprefix("$")):
        if m.group(1) is not None:
            steps.append(m.group(1))
        else:
            steps.append(int(m.group(2)) if m.group(2).isdigit() else "[...]")
    node_path: list[str] = []
    cur: Any = raw
    struct = kind  # the schema struct the error location is in, for listing its fields
    field: list[str | int] = []
    i = 0
    while i < len(steps):
        step = steps[i]
        nxt = steps[i + 1] if i + 1 < len(steps) else None
        last = i + 1 == len(steps)
        if struct in ("file", "subtree") and step == "root":
            cur = _get(cur, "root")
            node_path = [_raw_name(cur, "root")]
            struct = "node"
            i += 1
        elif struct == "node" and step == "children" and isinstance(nxt, int):
            cur = _get(_get(cur, "children"), nxt)
            node_path.append(_raw_name(cur, f"[{nxt}]"))
            i += 2
        elif struct in ("file", "subtree") and step == "wires" and isinstance(nxt, int):
            field = ["wires", nxt]
            struct = "wire"
            i += 2
        elif struct in ("file", "subtree") and step == "public" and last:
            field = ["public"]
            struct = "public"
            i += 1
        else:
            field.extend(steps[i:])
            struct = ""
            break
    name = "".join(
        f"[{s}]" if isinstance(s, int) else s if s == "[...]" else f".{s}" for s in field
    ).lstrip(".")
    parts = [label.strip()] if label else []
    if node_path:
        parts.append(f"node {'/'.join(node_path)!r}")
    if name:
        parts.append(f"{'key of ' if is_key else ''}field {name!r}")
    elif not parts:
        parts.append("top level")
    return f"{where}: {' '.join(parts)}: {_reword(text, struct)}"


def _reword(text: str, struct: str) -> str:
    m = re.match(r"Object contains unknown field `(.+)`$", text)
    if m:
        known = _STRUCT_FIELDS.get(struct)
        near = f"; expected one of {', '.join(known)}" if known else ""
        return f"unknown field {m.group(1)!r}{near}"
    m = re.match(r"Object missing required field `(.+)`$", text)
    if m:
        return f"missing required field {m.group(1)!r}"
    text = text.replace("`", "")
    return text[:1].lower() + text[1:]


def _get(value: Any, key: str | int) -> Any:
    try:
        return value[key]
    except (KeyError, IndexError, TypeError):
        return None


def _raw_name(node: Any, fallback: str) -> str:
    if isinstance(node, dict):
        name = node.get("name")
        if isinstance(name, str | int | float):
            return str(name)
        if name is None and isinstance(node.get("type"), str):
            return str(node["type"])
    return fallback


def read_tree_file(path: str | os.PathLike[str]) -> TreeFile:
    """Read and schema-check a file without building nodes (no registry needed)."""
    p = Path(path)
    return _parse(_decode(_read(p), _format_of(p), str(p)), str(p))


def _read(path: Path) -> bytes:
    try:
        return path.read_bytes()
    except OSError as exc:
        raise TreeFileError([f"{path}: cannot read: {exc.strerror or exc}"]) from None


# -- building -------------------------------------------------------------------------
def _is_type_option(cls: type[Node], key: str, port: Port) -> bool:
    """Options whose value is a type (Constant's ``type``) are written as type names.

    A node marks them with ``TYPE_OPTIONS = frozenset({...})``; otherwise an option
    declared as ``type`` or defaulting to a type (``Port(Any, Any)``) counts as one.
    """
    if key in getattr(cls, "TYPE_OPTIONS", ()):
        return True
    t, d = port.type, port.default
    if t is type or typing.get_origin(t) is type:
        return True
    return d is Any or isinstance(d, type) or typing.get_origin(d) is not None


def _split_ref(ref: str) -> tuple[str, str] | None:
    path, dot, port = ref.rpartition(".")
    if not dot or not path or not port:
        return None
    return path, port


class _Builder:
    """Builds one file's trees, collecting every problem instead of stopping at the first."""

    def __init__(
        self,
        spec: TreeFile,
        where: str,
        registry: NodeRegistry,
        base: Path | None,
        stack: tuple[Path, ...],
        cache: dict[Path, TreeFile],
    ) -> None:
        self.spec = spec
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
        for name in self.spec.subtrees:
            self._check_subtree(name)
        spec = self.spec
        tree = self._tree(spec.root, spec.wires, spec.public, spec.name, "", clock)
        if self.problems or tree is None:
            raise TreeFileError(self.problems)
        _set_info(tree, FileInfo(spec.description, spec.public))
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
        root = self._node(root_spec, None, ctx, failed)
        if root is None:
            return None
        tree = Tree(root, name=name, clock=clock)
        wired: set[tuple[str, str]] = set()
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
    def _check_subtree(self, name: str) -> bool:
        """Build a definition once to report its problems; cached, cycles reported."""
        if name in self._checked:
            return self._checked[name]
        if name in self._building:
            return False
        self._building.append(name)
        before = len(self.problems)
        ok = self._build_subtree(name) is not None and len(self.problems) == before
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
        _set_info(tree, FileInfo(sub.description, sub.public))
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
            inner = _Builder(
                spec, str(path), self.registry, path.parent, (*self.stack, resolved), self.cache
            )
            tree = inner.build_main(None)
        except TreeFileError as exc:
            for p in exc.problems:
                self.fail(f"{ctx}(file {ref}): {p}")
            return None
        tree.name = name
        info = file_info(tree)
        _set_info(tree, dataclasses.replace(info, source=resolved))
        return tree, info.public or PublicSpec()

    # -- nodes ------------------------------------------------------------------------
    def _node(self, spec: NodeSpec, parent: str | None, ctx: str, failed: list[str]) -> Node | None:
        name = spec.name
        if name is None:
            tree_ref = spec.options.get("tree")
            name = tree_ref if spec.type == "Subtree" and isinstance(tree_ref, str) else spec.type
        path = name if parent is None else f"{parent}/{name}"
        loc = f"{ctx}node {path!r}"
        if not name or "/" in name or "." in name:
            self.fail(f"{loc} field 'name': expected a non-empty name without '/' or '.'")
            failed.append(path)
            return None
        if spec.type == "Subtree":
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
                    f"{_near(key, declared)}; options: {', '.join(declared) or 'none'}"
                )
                ok = False
                continue
            if _is_type_option(cls, key, port):
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
                options[key] = check_value(value, port.type, where)
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
                f"{_near(ref, self.spec.subtrees)}; subtrees: {known}"
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
                    f"{_near(key, node.input_ports)}; inputs: "
                    f"{', '.join(node.input_ports) or 'none'}"
                )
                continue
            try:
                node.set_input(
                    key, check_value(value, port.type, f"{self.where}: {loc} input {key!r}")
                )
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


def _under(path: str, failed: list[str]) -> bool:
    return any(path == f or path.startswith(f + "/") for f in failed)


def _near(word: str, options: Iterable[str]) -> str:
    near = difflib.get_close_matches(word, list(options), n=3, cutoff=0.6)
    return f" (did you mean {', '.join(near)}?)" if near else ""


def _strip_self(msg: str, name: str, tname: str) -> str:
    """Drop the node's own name from a core error, the path already says which node."""
    for prefix in (f"node {name!r} ({tname}): ", f"node {name!r} ", f"{tname} {name!r}: "):
        if msg.startswith(prefix):
            return msg[len(prefix) :]
    return msg


def _load(
    data: bytes | str,
    fmt: Format,
    where: str,
    registry: NodeRegistry | None,
    clock: TimeSource | None,
    base: Path | None,
    source: Path | None,
) -> Tree:
    spec = _parse(_decode(data, fmt, where), where)
    reg = registry if registry is not None else default_registry()
    stack = (source.resolve(),) if source is not None else ()
    return _Builder(spec, where, reg, base, stack, {}).build_main(clock)


def load_tree(
    path: str | os.PathLike[str],
    registry: NodeRegistry | None = None,
    *,
    clock: TimeSource | None = None,
) -> Tree:
    """Build the tree a ``.yaml``/``.yml``/``.json`` file describes; raises TreeFileError."""
    p = Path(path)
    return _load(_read(p), _format_of(p), str(p), registry, clock, p.parent, p)


def loads_tree(
    text: str | bytes,
    fmt: Format = "yaml",
    registry: NodeRegistry | None = None,
    *,
    clock: TimeSource | None = None,
    name: str = "<string>",
    base: str | os.PathLike[str] | None = None,
) -> Tree:
    """Like :func:`load_tree` for text; ``name`` labels errors, ``base`` resolves file refs."""
    if fmt not in ("yaml", "json"):
        raise ValueError(f"format {fmt!r}: expected 'yaml' or 'json'")
    return _load(text, fmt, name, registry, clock, Path(base) if base else None, None)


def validate_file(path: str | os.PathLike[str], registry: NodeRegistry | None = None) -> list[str]:
    """Every problem of a file (empty if it loads); never raises for a bad file."""
    try:
        load_tree(path, registry)
    except TreeFileError as exc:
        return exc.problems
    return []


# -- dumping --------------------------------------------------------------------------
def _lists(value: Any) -> Any:
    """Tuples as lists, as a file would give them back (so dumps compare equal)."""
    if isinstance(value, list | tuple):
        return [_lists(v) for v in value]
    if isinstance(value, dict):
        return {k: _lists(v) for k, v in value.items()}
    return value


def _same(a: Any, b: Any) -> bool:
    try:
        return bool(a == b) and type(a) is type(b)
    except Exception:
        return False


class _Dumper:
    def __init__(self, registry: NodeRegistry, base: Path | None) -> None:
        self.registry = registry
        self.base = base
        self.subtrees: dict[str, SubtreeSpec] = {}

    def fail(self, msg: str) -> typing.NoReturn:
        raise TreeFileError([f"<dump>: {msg}"])

    def encode(self, value: Any, loc: str) -> Any:
        try:
            return _lists(msgspec.to_builtins(value))
        except (TypeError, ValueError) as exc:
            self.fail(f"{loc}: value {value!r} cannot be written to a file ({exc})")

    def tree(self, tree: Tree, skip: set[tuple[int, str]]) -> tuple[NodeSpec, list[WireSpec]]:
        wired = {(id(w.target), w.target_port) for w in tree.wires}
        root = self.node(tree.root, wired | skip)
        wires = [
            WireSpec(f"{w.source.path}.{w.source_port}", f"{w.target.path}.{w.target_port}")
            for w in tree.wires
        ]
        return root, wires

    def node(self, n: Node, skip: set[tuple[int, str]]) -> NodeSpec:
        loc = f"node {n.path!r}"
        options: dict[str, Any] = {}
        if isinstance(n, Subtree):
            tname = "Subtree"
            options["tree"] = self.subtree(n)
        else:
            try:
                tname = self.registry.name_of(type(n))
            except RegistryError as exc:
                self.fail(f"{loc} field 'type': {exc}")
            cls = type(n)
            for key, port in cls.OPTIONS.items():
                value = n.options.get(key)
                if not port.required and _same(value, port.default_value()):
                    continue
                if _is_type_option(cls, key, port):
                    try:
                        options[key] = self.registry.format_type(value)
                    except RegistryError as exc:
                        self.fail(f"{loc} option {key!r}: {exc}")
                else:
                    options[key] = self.encode(value, f"{loc} option {key!r}")
        inputs = {
            key: self.encode(value, f"{loc} input {key!r}")
            for key, value in n.inputs.items()
            if (id(n), key) not in skip
            and key in n.input_ports
            and not _same(value, n.input_ports[key].default_value())
        }
        children = [self.node(c, skip) for c in n.children]
        return NodeSpec(type=tname, name=n.name, options=options, inputs=inputs, children=children)

    def subtree(self, n: Subtree) -> str:
        inner = n.inner
        info = file_info(inner)
        if info.source is not None:
            ref = info.source
            if self.base is not None:
                ref = Path(os.path.relpath(info.source, self.base.resolve()))
            spec = SubtreeSpec(file=ref.as_posix())
        else:
            in_map: dict[str, tuple[Node, str]] = n._in_map
            out_map: dict[str, tuple[Node, str]] = n._out_map
            public = PublicSpec(
                inputs={k: f"{node.path}.{p}" for k, (node, p) in in_map.items()},
                outputs={k: f"{node.path}.{p}" for k, (node, p) in out_map.items()},
            )
            skip = {(id(node), p) for node, p in in_map.values()}
            root, wires = self.tree(inner, skip)
            spec = SubtreeSpec(
                description=info.description,
                root=root,
                wires=wires,
                public=public if public.inputs or public.outputs else None,
            )
        name, k = inner.name, 2
        while name in self.subtrees and self.subtrees[name] != spec:
            name, k = f"{inner.name}_{k}", k + 1
        self.subtrees[name] = spec
        return name


def dump_tree(
    tree: Tree,
    registry: NodeRegistry | None = None,
    *,
    base: str | os.PathLike[str] | None = None,
) -> TreeFile:
    """The :class:`TreeFile` describing ``tree``; ``base`` makes subtree file refs relative.

    Options and inputs equal to their defaults are left out; wired inputs are written
    as wires, never as values.
    """
    d = _Dumper(
        registry if registry is not None else default_registry(), Path(base) if base else None
    )
    root, wires = d.tree(tree, set())
    info = file_info(tree)
    return TreeFile(
        btcap=SCHEMA_VERSION,
        name=tree.name,
        description=info.description,
        root=root,
        wires=wires,
        subtrees=dict(sorted(d.subtrees.items())),
        public=info.public if info.public and (info.public.inputs or info.public.outputs) else None,
    )


class _YamlDumper(yaml.SafeDumper):
    """Block style for structure, flow style for short flat lists and mappings."""


def _flat(values: Iterable[Any]) -> bool:
    return all(v is None or isinstance(v, (str, int, float, bool)) for v in values)


def _represent_list(dumper: yaml.SafeDumper, data: list[Any]) -> yaml.Node:
    flow = _flat(data) and len(repr(data)) <= 60
    return dumper.represent_sequence("tag:yaml.org,2002:seq", data, flow_style=flow)


def _represent_dict(dumper: yaml.SafeDumper, data: dict[Any, Any]) -> yaml.Node:
    flow = _flat(data.values()) and len(repr(data)) <= 72
    return dumper.represent_mapping("tag:yaml.org,2002:map", data.items(), flow_style=flow)


_YamlDumper.add_representer(list, _represent_list)
_YamlDumper.add_representer(dict, _represent_dict)


def dumps_tree(
    tree: Tree | TreeFile,
    fmt: Format = "yaml",
    registry: NodeRegistry | None = None,
    *,
    base: str | os.PathLike[str] | None = None,
) -> str:
    """The file text for a tree (or an already dumped :class:`TreeFile`)."""
    spec = tree if isinstance(tree, TreeFile) else dump_tree(tree, registry, base=base)
    if fmt == "json":
        return msgspec.json.format(msgspec.json.encode(spec), indent=2).decode() + "\n"
    if fmt != "yaml":
        raise ValueError(f"format {fmt!r}: expected 'yaml' or 'json'")
    data = msgspec.to_builtins(spec)
    return yaml.dump(data, Dumper=_YamlDumper, sort_keys=False, allow_unicode=True, width=100)


def save_tree(
    tree: Tree,
    path: str | os.PathLike[str],
    registry: NodeRegistry | None = None,
) -> Path:
    """Write ``tree`` to ``path``, YAML or JSON by suffix; returns the path."""
    p = Path(path)
    fmt = _format_of(p)
    text = dumps_tree(tree, fmt, registry, base=p.parent)
    try:
        p.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise TreeFileError([f"{p}: cannot write: {exc.strerror or exc}"]) from None
    return p
