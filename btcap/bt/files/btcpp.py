"""BehaviorTree.CPP v4 XML (as Groot2 draws it) read into a btcap tree file.

The XML becomes a :class:`~btcap.bt.files.schema.TreeFile` that the usual builder turns
into a Tree, so an XML tree is checked exactly like a YAML one. What the translation
does:

- every ``<BehaviorTree ID>`` of the file and of the files it ``<include>``s
  (:mod:`~btcap.bt.files.btcpp_doc`) is a subtree; the one asked for (``main=``),
  ``main_tree_to_execute`` or the only one is the root; ``<SubTree ID>`` nodes use
  them, remapping ports by attribute (``goal="{target}"``, a literal ``goal="3"``) or
  by ``_autoremap="true"``;
- blackboard entries become wires: the one node output writing ``{key}`` feeds every
  input reading it. In a subtree, an entry read but not written inside is a public
  input, and every entry written inside is a public output;
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
import re
from pathlib import Path
from typing import Any

from btcap.bt.files.btcpp_doc import Documents, XmlOptions
from btcap.bt.files.btcpp_elements import BTCPP_BUILTINS, ElementReader, Ref, Scope, literal
from btcap.bt.files.btcpp_nodes import UNSUPPORTED, MappingError, parse_bool
from btcap.bt.files.btcpp_stubs import infer_models, load_scripts, make_stub
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

__all__ = ["XmlTranslator", "relabel"]


@dataclasses.dataclass(frozen=True)
class _Def:
    """A translated BehaviorTree and the types of its public ports."""

    spec: SubtreeSpec
    inputs: dict[str, Any]
    outputs: dict[str, Any]


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
    ) -> None:
        self.root = root
        self.where = where
        self.registry = registry
        self.options = options or XmlOptions()
        self.folder = folder  # where <include path> is relative to
        self.source = source  # the file itself, if read from one (include cycles)
        self.reader = ElementReader(where, registry, {}, self._subtree)
        self.problems = self.reader.problems
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
            self._insert(problem)
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

    def _insert(self, problem: str) -> None:
        """Put ``problem`` before the first one of its file at a later line."""
        m = _LINE.match(problem)
        if m is None:  # the closing "what to do" line
            self.problems.append(problem)
            return
        for i, other in enumerate(self.problems):
            n = _LINE.match(other)
            if n is not None and n.group(1) == m.group(1) and int(n.group(2)) > int(m.group(2)):
                self.problems.insert(i, problem)
                return
        self.problems.append(problem)

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
        try:
            scripts = load_scripts(self.options.stub_script)
        except TreeFileError as exc:
            self.problems.extend(exc.problems)
            return
        registry = self.registry.copy()
        for kind, model in list(self.models.items()):
            if (
                model.tag == "SubTree"
                or kind in BTCPP_BUILTINS
                or registry.xml_type(kind) is not None
            ):
                continue
            try:
                registry.register(make_stub(model, scripts), kind)
            except (TreeFileError, RegistryError) as exc:
                msgs = exc.problems if isinstance(exc, TreeFileError) else [str(exc)]
                self.problems.extend(msgs)
                continue
            self.reader.seen_models[kind] = self.models.pop(kind)  # its own ports
        unsure = infer_models(self.trees.values(), lambda k: self._unknown(k, registry))
        for kind, model in unsure.items():
            registry.register(make_stub(model, scripts), kind)
            ports = ", ".join(p.attrs["name"] for p in model.children) or "none"
            self.warnings.append(
                f"{model.where or self.where}: line {model.line}: {kind} is declared in no "
                f"<TreeNodesModel>; stubbed from its use ({model.tag}; inputs: {ports})"
            )
        self.registry = self.reader.registry = registry

    def _unknown(self, kind: str, registry: NodeRegistry) -> bool:
        """Whether a type used in the XML is neither BehaviorTree.CPP's, known nor modelled."""
        return not (
            kind in BTCPP_BUILTINS
            or kind in UNSUPPORTED
            or kind in self.models
            or registry.xml_type(kind) is not None
        )

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
        """Wire each entry's writer to its readers; what crosses the tree's edge is public."""
        wires: list[WireSpec] = []
        public = PublicSpec()
        inputs: dict[str, Any] = {}
        outputs: dict[str, Any] = {}
        main = scope.tree == self.main
        for key in dict.fromkeys([*scope.writers, *scope.readers]):
            ws, rs = scope.writers.get(key, []), scope.readers.get(key, [])
            if not ws and key in scope.unsure:
                continue  # perhaps written by a node already reported as unknown
            if len(ws) > 1:
                lines = ", ".join(str(w.line) for w in ws)
                self.fail(
                    ws[1].line,
                    f"{{{key}}} is written by {len(ws)} node ports (lines "
                    f"{lines}); btcap feeds an input from exactly one output",
                )
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
            elif main:
                for r in rs:
                    self.fail(
                        r.line,
                        f"{{{key}}} is read here but no node writes it; btcap "
                        f"has no outside blackboard: write it with a node output or "
                        f"<SetBlackboard output_key={key!r} value=...>",
                    )
            elif len(rs) > 1:
                lines = ", ".join(str(r.line) for r in rs)
                self.fail(
                    rs[1].line,
                    f"{{{key}}} comes from outside BehaviorTree "
                    f"{scope.tree!r} and is read by {len(rs)} node ports (lines "
                    f"{lines}); btcap feeds a subtree input to one node port",
                )
            else:
                public.inputs[key] = f"{rs[0].path}.{rs[0].port}"
                inputs[key] = rs[0].type
        spec = SubtreeSpec(root=root, wires=wires, public=public)
        return _Def(spec, inputs, outputs)

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
        self._check_model(tid, done)
        spec = NodeSpec(type="Subtree", name=name, options={"tree": tid})
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
        for key in attrs:
            self.fail(
                el.line,
                f"<SubTree ID={tid!r}> port {key!r}: the tree neither reads it "
                f"from outside ({', '.join(done.inputs) or 'nothing'}) nor writes it "
                f"({', '.join(done.outputs) or 'nothing'})",
            )
        return spec

    def _check_model(self, tid: str, done: _Def) -> None:
        """A ``<SubTree>`` entry of TreeNodesModel must agree with what the tree does."""
        model = self.models.get(tid)
        if model is None or model.tag != "SubTree":
            return
        del self.models[tid]  # checked once, at its first use
        for port in model.children:
            key = port.attrs.get("name", "")
            if port.tag == "input_port" and key not in done.inputs:
                self.fail(
                    port.line,
                    f"<TreeNodesModel> SubTree {tid!r} input_port {key!r}: the tree does not "
                    f"read {{{key}}} from outside (it reads: "
                    f"{', '.join(done.inputs) or 'nothing'})",
                )
            elif port.tag == "output_port" and key not in done.outputs:
                self.fail(
                    port.line,
                    f"<TreeNodesModel> SubTree {tid!r} output_port {key!r}: the tree does not "
                    f"write {{{key}}} (it writes: {', '.join(done.outputs) or 'nothing'})",
                )


_LINE = re.compile(r"^(.*?): line (\d+): ")
_WHERE = re.compile(
    r"^(?:subtree '(?P<tree>[^']+)' )?(?:node '(?P<path>[^']+)'|wires\[(?P<i>\d+)\])"
)


def relabel(problems: list[str], where: str, t: XmlTranslator) -> list[str]:
    """Builder problems (named by node path) with the XML line of the node or wire."""
    out = []
    prefix = f"{where}: "
    for p in problems:
        rest = p.removeprefix(prefix)
        m = _WHERE.match(rest)
        line = None
        at = where
        if m is not None:
            tree = m.group("tree") or t.main
            at = t.tree_where.get(tree, where)
            if m.group("path") is not None:
                line = t.node_lines.get((tree, m.group("path")))
            else:
                line = t.wire_lines.get((tree, int(m.group("i"))))
        out.append(p if line is None else f"{at}: line {line}: {rest}")
    return out
