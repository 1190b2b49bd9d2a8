"""BehaviorTree.CPP v4 XML (as Groot2 draws it) read into a btcap tree file.

The XML becomes a :class:`~btcap.bt.files.schema.TreeFile` that the usual builder turns
into a Tree, so an XML tree is checked exactly like a YAML one. What the translation
does:

- every ``<BehaviorTree ID>`` of the file and of the files it ``<include>``s
  (:mod:`~btcap.bt.files.btcpp_doc`) is a subtree; the one asked for (``main=``),
  ``main_tree_to_execute`` or the only one is the root; ``<SubTree ID>`` nodes use
  them, remapping ports by attribute (``goal="{target}"``, a literal ``goal="3"``) or
  by ``_autoremap="true"``;
- blackboard entries become wires where a wire reads what the entry would hold: the one
  output writing ``{key}`` feeds the inputs that tick only after it succeeded in the
  same run of a sequence. Every other entry is a :class:`~btcap.bt.blackboard.Blackboard`
  entry (:mod:`btcap.bt.files.board`): several writers (the last write wins), a node
  reading and writing it, a reader before its writer, one the application supplies
  (``entries=``, ``tree.blackboard``), ``{@key}`` (the main tree's). A SubTree's entry
  remapped to a parent's entry is that entry. In a subtree, an entry read but not
  written inside is a public input, and one written there is a public output;
- standard nodes map to btcap's (:mod:`~btcap.bt.files.btcpp_nodes`); other node types
  are looked up among the registry's user types (your own nodes, capability interfaces
  and their bridges; never btcap's own ``Wait`` or ``Log``, which XML spells
  ``btcap.Log``), checked against ``<TreeNodesModel>`` where it declares them, or
  stubbed from it (:mod:`~btcap.bt.files.btcpp_stubs`);
- literal attribute values are converted to the port's declared type (``;`` separates
  list items, as in BehaviorTree.CPP).

Whatever cannot be mapped is reported with the file, the line and the element.
"""

from __future__ import annotations

import dataclasses
import difflib
from collections.abc import Collection
from pathlib import Path
from typing import Any

from btcap.bt.files.board import TreeBoard
from btcap.bt.files.btcpp_doc import Documents, XmlOptions
from btcap.bt.files.btcpp_elements import KEY, ElementReader, Ref, Scope, literal
from btcap.bt.files.btcpp_entries import before, entry_type, merged, passing, paths
from btcap.bt.files.btcpp_lines import check_subtree_model, insert_problem
from btcap.bt.files.btcpp_nodes import MappingError, parse_bool
from btcap.bt.files.btcpp_rules import BUILTIN_PORTS, check_builtin_model
from btcap.bt.files.btcpp_stubs import stub_registry
from btcap.bt.files.btcpp_uses import EntryUses
from btcap.bt.files.schema import (
    SCHEMA_VERSION,
    NodeSpec,
    PublicSpec,
    SubtreeSpec,
    TreeFile,
    TreeFileError,
    WireSpec,
)
from btcap.bt.files.xmlread import MAX_DEPTH, XmlElement
from btcap.bt.registry import NodeRegistry, RegistryError

__all__ = ["XmlTranslator"]


@dataclasses.dataclass(frozen=True)
class _Def:
    """A translated BehaviorTree and the types of its public ports."""

    spec: SubtreeSpec
    inputs: dict[str, Any]
    outputs: dict[str, Any]
    #: Its blackboard entries (not ports): the type and whether a node inside writes it.
    cells: dict[str, tuple[Any, bool]] = dataclasses.field(default_factory=dict)
    #: Its outputs written whenever it succeeds (:func:`btcpp_entries.before`).
    sure: frozenset[str] = frozenset()
    #: Entries only a node of unknown type uses: perhaps ports, reported as that type.
    unsure: frozenset[str] = frozenset()


class XmlTranslator:
    """Translates one XML document, collecting every problem with its line."""

    def __init__(
        self,
        root: XmlElement,
        where: str,
        registry: NodeRegistry,
        options: XmlOptions | None = None,
        folder: Path | None = None,
        source: Path | None = None,
        entries: Collection[str] = (),
    ) -> None:
        self.root = root
        #: Entries the application supplies: blackboard entries even if a node writes them.
        self.entries = frozenset(entries)
        #: The blackboard entries of each BehaviorTree, for the builder.
        self.boards: dict[str, TreeBoard] = {}
        #: Per BehaviorTree, its entries that are a SubTree's blackboard entries:
        #: (the SubTree node and the entry inside, whether the SubTree writes it).
        self.aliases: dict[str, dict[str, list[tuple[Ref, bool]]]] = {}
        #: Entries some tree uses as ``{@key}``: the main tree's are blackboard entries.
        self.globals: set[str] = set()
        self.where = where
        self.registry = registry
        self.options = options or XmlOptions()
        self.folder = folder  # where <include path> is relative to
        self.source = source  # the file itself, if read from one (include cycles)
        self.reader = ElementReader(where, registry, {}, self._subtree)
        self.problems = self.reader.problems
        #: Each node's ports using entries, and the entries the application must set.
        self.uses = EntryUses()
        #: What BehaviorTree.CPP warns about and btcap reads anyway.
        self.warnings: list[str] = []
        self.trees: dict[str, XmlElement] = {}
        self.models = self.reader.models
        self.defs: dict[str, _Def | None] = {}
        self.active: list[str] = []
        self.bases: list[int] = []  # how deep each active tree's root sits in the main tree
        self.heights: dict[str, int] = {}  # levels of nodes a tree adds, its subtrees' too
        self.used: set[str] = set()
        #: (BehaviorTree ID, node path) -> line, and (ID, wire index) -> line, for relabel.
        self.node_lines = self.reader.node_lines
        self.wire_lines: dict[tuple[str, int], int] = {}
        #: BehaviorTree ID -> the file it is in (an <include>d one, or this one).
        self.tree_where: dict[str, str] = {}
        self.main = ""

    def fail(self, line: int, msg: str) -> None:
        self.reader.fail(line, msg)

    def _fail_in(self, where: str, line: int, msg: str) -> None:
        self.problems.append(f"{where}: line {line}: {msg}" if line > 0 else f"{where}: {msg}")

    # -- document ---------------------------------------------------------------------
    def translate(self) -> TreeFile:
        docs = Documents(self._fail_in, self.warnings.append)
        if not docs.root(self.root, self.where):
            raise TreeFileError(self.problems)
        chain = (self.source.resolve(),) if self.source is not None else ()
        docs.read(self.root, self.where, self.folder, chain)
        for path in self.options.models:
            docs.model_file(path)
        self.trees = docs.trees
        self.tree_where = {t: el.where or self.where for t, el in self.trees.items()}
        self.models.update(docs.models)
        for kind, model in list(self.models.items()):
            if kind in BUILTIN_PORTS and model.tag != "SubTree":  # BehaviorTree.CPP's ports
                check_builtin_model(self.models.pop(kind), self.reader.fail, self.where)
        if self.options.stub_missing:
            self._stub()
        if self.problems:
            raise TreeFileError(self.problems)
        main = self._main()
        self.main = main
        top = self._definition(main, self.root.line)
        for tid in self.trees:
            self._definition(tid, self.trees[tid].line)
        for problem in self.reader.unknown_problems():
            insert_problem(self.problems, problem)
        if self.problems or top is None or top.spec.root is None:
            raise TreeFileError(self.problems)
        subtrees = {t: d.spec for t, d in self.defs.items() if d and (t != main or t in self.used)}
        return TreeFile(
            btcap=SCHEMA_VERSION,
            name=main,
            root=top.spec.root,
            wires=top.spec.wires,
            subtrees=subtrees,
        )

    def _main(self) -> str:
        """The tree to run: asked for, main_tree_to_execute, or the only one."""
        ids = ", ".join(self.trees) or "none"
        main = self.options.main
        if main is not None:
            if main not in self.trees:
                self.fail(self.root.line, f"main tree {main!r}: no such BehaviorTree ({ids})")
                raise TreeFileError(self.problems)
            return main
        main = self.root.attrs.get("main_tree_to_execute")
        if main is not None:
            return main
        if not self.trees:
            self.fail(self.root.line, "no <BehaviorTree> in this file")
            raise TreeFileError(self.problems)
        if len(self.trees) != 1:
            self.fail(
                self.root.line,
                f"main_tree_to_execute missing and {len(self.trees)} BehaviorTrees "
                f"({ids}); say which one to run (--main TREE, or main= when loading)",
            )
            raise TreeFileError(self.problems)
        return next(iter(self.trees))

    def _stub(self) -> None:
        """Register a stand-in for each declared type no registered node type provides."""
        registry = stub_registry(
            self.registry,
            self.models,
            self.trees.values(),
            self.options.stub_script,
            self.where,
            (self.problems, self.warnings),
            self.reader.seen_models,
        )
        if registry is not None:
            self.registry = self.reader.registry = registry

    # -- BehaviorTrees ----------------------------------------------------------------
    def _definition(self, tid: str, line: int, at: int = 0) -> _Def | None:
        if tid in self.defs:
            return self.defs[tid]
        if tid in self.active:
            chain = " -> ".join([*self.active[self.active.index(tid) :], tid])
            self.fail(line, f"<SubTree ID={tid!r}>: the tree uses itself ({chain})")
            return None
        el = self.trees.get(tid)
        if el is None:
            near = difflib.get_close_matches(tid, list(self.trees), n=3, cutoff=0.6)
            hint = f" (did you mean {', '.join(near)}?)" if near else ""
            self.fail(
                line,
                f"no <BehaviorTree ID={tid!r}>{hint}; trees: {', '.join(self.trees) or 'none'}",
            )
            return None
        self.active.append(tid)
        self.bases.append(at)
        outer, self.reader.where = self.reader.where, self.tree_where.get(tid, self.where)
        scope = Scope(tid)
        if len(el.children) != 1:
            self.fail(
                el.line,
                f"<BehaviorTree ID={tid!r}> must hold exactly one root node, "
                f"has {len(el.children)}",
            )
        spec = self.reader.node(el.children[0], None, scope, set()) if el.children else None
        self.active.pop()
        self.bases.pop()
        done = self._resolve(scope, spec) if spec is not None else None
        self.reader.where = outer
        self.defs[tid] = done
        self.heights[tid] = self._height(spec) if spec is not None else 0
        return done

    def _height(self, spec: NodeSpec) -> int:
        below = [self._height(c) for c in spec.children]
        if spec.type == "Subtree":
            below.append(self.heights.get(spec.options["tree"], 0))
        return 1 + max(below, default=0)

    def _too_deep(self, el: XmlElement, tid: str, depth: int) -> bool:
        """Subtrees within subtrees nest the built tree, which loading recurses over."""
        if depth <= MAX_DEPTH:
            return False
        self.fail(
            el.line,
            f"<SubTree ID={tid!r}> nests the tree {depth} nodes deep (subtrees within "
            f"subtrees); btcap reads at most {MAX_DEPTH}",
        )
        return True

    def _resolve(self, scope: Scope, root: NodeSpec) -> _Def:
        """Wire each entry's writer to its readers; what crosses the tree's edge is public.

        Entries wires cannot express are blackboard entries (:meth:`_cell`).
        """
        wires: list[WireSpec] = []
        public = PublicSpec()
        inputs: dict[str, Any] = {}
        outputs: dict[str, Any] = {}
        main = scope.tree == self.main
        writers, readers = merged(scope.writers, main), merged(scope.readers, main)
        aliases = merged(self.aliases.get(scope.tree, {}), main)
        board = self.boards.setdefault(scope.tree, TreeBoard())
        cells: dict[str, tuple[Any, bool]] = {}
        specs = dict(paths(root, None))
        order = {path: i for i, path in enumerate(specs)}  # depth first
        sure: set[str] = set()
        scripted = merged(scope.scripted, main)
        board.scripts.extend(scope.script_nodes)
        for key in dict.fromkeys([*writers, *readers, *aliases, *scripted]):
            ws, rs, al = writers.get(key, []), readers.get(key, []), aliases.get(key, [])
            if not ws and not al and key in scope.unsure and key not in scripted:
                continue  # perhaps written by a node already reported as unknown
            self.uses.add(scope.tree, key, (ws, rs, al), scripted.get(key, []))
            where = self.tree_where.get(scope.tree, self.where)
            self.uses.need(scope.tree, key, (ws, rs, al), scripted.get(key, []), order, where)
            if key in scripted or self._is_cell(key, (ws, rs, al), main, specs):
                self._cell(scope, key, (ws, rs, al), board, cells, scripted.get(key, []))
                continue
            if ws:
                w = ws[0]
                for r in rs:
                    self.wire_lines[(scope.tree, len(wires))] = r.line
                    wires.append(WireSpec(f"{w.path}.{w.port}", f"{r.path}.{r.port}"))
                tp = w.type
                if key in scope.constants:
                    tp = self._constant(key, scope, rs[0].type if rs else Any)
                public.outputs[key] = f"{w.path}.{w.port}"
                outputs[key] = tp
                if passing(w.path.split("/"), 0, specs) and self._sure(w, specs):
                    sure.add(key)
            else:
                public.inputs[key] = f"{rs[0].path}.{rs[0].port}"
                inputs[key] = rs[0].type
        spec = SubtreeSpec(root=root, wires=wires, public=public)
        return _Def(
            spec,
            inputs,
            outputs,
            cells,
            frozenset(sure),
            frozenset(scope.unsure - {*inputs, *outputs, *cells}),
        )

    def _is_cell(
        self,
        key: str,
        refs: tuple[list[Ref], list[Ref], list[tuple[Ref, bool]]],
        main: bool,
        specs: dict[str, NodeSpec],
    ) -> bool:
        """Whether an entry needs the blackboard: what one output wired to inputs is not.

        A wire holds the writer's output, cleared when the writer is reset; an entry
        keeps its value until written again. They agree when a reader can only tick
        after the writer succeeded in the same run of a sequence (:func:`before`).
        """
        ws, rs, al = refs
        if key.startswith("@") or al or len(ws) > 1:
            return True
        if ws and any(r.path == ws[0].path for r in rs):
            return True  # read and written by one node: it reads the value before its own
        if ws and rs and not main:
            return True  # remapped, its readers see the parent's value before the writer's
        if len(rs) > 1 and not main:
            return True  # from outside, to several ports
        if main and (not ws or key in self.entries or key in self.globals):
            return True
        if not ws:
            return False  # a subtree's input from outside
        return not (self._sure(ws[0], specs) and all(before(ws[0].path, r.path, specs) for r in rs))

    def _sure(self, writer: Ref, specs: dict[str, NodeSpec]) -> bool:
        """Whether the node has written the output whenever it succeeds: a SubTree has if
        its tree has (a node of yours is taken to write its outputs when it succeeds)."""
        spec = specs[writer.path]
        if spec.type != "Subtree":
            return True
        done = self.defs.get(spec.options["tree"])
        return done is not None and writer.port in done.sure

    def _cell(
        self,
        scope: Scope,
        key: str,
        refs: tuple[list[Ref], list[Ref], list[tuple[Ref, bool]]],
        board: TreeBoard,
        cells: dict[str, tuple[Any, bool]],
        scripts: list[tuple[Ref, bool]] = (),  # type: ignore[assignment]
    ) -> None:
        """A blackboard entry: every port using it reads or writes it, one type for all
        (scripts take the type the ports give it, or the type of its first value)."""
        ws, rs, al = refs
        if key in scope.constants:
            self._constant(key, scope, rs[0].type if rs else Any)
        written = [(w.line, w.type) for w in ws] + [(r.line, r.type) for r, w in al if w]
        read = [(r.line, r.type) for r in rs] + [(r.line, r.type) for r, w in al if not w]
        tp = entry_type(key, written, read, self.fail)
        board.writes.extend((w.path, w.port, key) for w in ws)
        board.reads.extend((r.path, r.port, key) for r in rs)
        for r, _ in al:
            board.remaps.setdefault(r.path, {})[r.port] = key
        if key.startswith("@"):
            self.globals.add(key[1:])
        else:
            cells[key] = (tp, bool(written) or any(w for _, w in scripts))

    def _constant(self, key: str, scope: Scope, tp: Any) -> Any:
        """Type a SetBlackboard value by the port that reads it."""
        spec, text = scope.constants[key]
        try:
            spec.options["type"] = self.registry.format_type(tp)
        except RegistryError:
            return Any  # an unnamed type: the text is passed on as it is
        spec.options["value"] = literal(text, tp)
        return tp

    # -- nodes ------------------------------------------------------------------------
    def _subtree(
        self, el: XmlElement, attrs: dict[str, str], name: str, path: str, scope: Scope
    ) -> NodeSpec | None:
        tid = attrs.pop("ID", "")
        if not tid:
            self.fail(el.line, "<SubTree> without an ID naming its BehaviorTree")
            return None
        try:
            auto = parse_bool(attrs.pop("_autoremap", "false"))
        except MappingError as exc:
            self.fail(el.line, f"<SubTree ID={tid!r}> _autoremap: {exc}")
            return None
        at = (self.bases[-1] if self.bases else 0) + path.count("/") + 1
        if self._too_deep(el, tid, at):
            return None
        done = self._definition(tid, el.line, at)
        self.used.add(tid)
        if done is None or self._too_deep(el, tid, at + self.heights[tid]):
            return None
        check_subtree_model(self.models, tid, done, self.fail)
        if not auto:
            self.uses.not_passed(tid, set(attrs), f"<SubTree ID={tid!r}> at line {el.line}")
        spec = NodeSpec(type="Subtree", name=name, options={"tree": tid})
        for key, (tp, written) in done.cells.items():  # one entry inside and out
            if key in attrs or auto:
                text = attrs.pop(key, "{=}")
                entry = self.reader.entry(text, key, el, reading=True)
                if entry is None:
                    board = self.boards.setdefault(scope.tree, TreeBoard())
                    board.initial.setdefault(path, {})[key] = text
                elif entry:
                    aliased = self.aliases.setdefault(scope.tree, {}).setdefault(entry, [])
                    aliased.append((Ref(path, key, el.line, tp), written))
        for ports, reading in ((done.inputs, True), (done.outputs, False)):
            for key, tp in ports.items():
                if key in attrs:
                    text = attrs.pop(key)
                elif auto:
                    text = "{=}"
                else:
                    continue
                entry = self.reader.entry(text, key, el, reading=reading)
                if entry is None:
                    spec.inputs[key] = literal(text, tp)
                elif entry:
                    refs = scope.readers if reading else scope.writers
                    refs.setdefault(entry, []).append(Ref(path, key, el.line, tp))
        for key, text in attrs.items():
            if key in done.unsure:  # the unknown type's error says why; perhaps its port
                scope.unsure.update(m[1] for m in [KEY.match(text)] if m)
                continue
            self.fail(
                el.line,
                f"<SubTree ID={tid!r}> port {key!r}: the tree neither reads it "
                f"from outside ({', '.join(done.inputs) or 'nothing'}) nor writes it "
                f"({', '.join(done.outputs) or 'nothing'})",
            )
        return spec
