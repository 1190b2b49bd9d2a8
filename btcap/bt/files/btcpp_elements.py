"""The elements of a BehaviorTree.CPP v4 XML tree as btcap node specs, one at a time.

:class:`ElementReader` turns one node element (and those below it) into a
:class:`~btcap.bt.files.schema.NodeSpec`, recording in a :class:`Scope` which ports
write and read each blackboard entry; :mod:`btcap.bt.files.btcpp` then wires them.
"""

from __future__ import annotations

import difflib
import re
import typing
from collections.abc import Callable
from typing import Any

from btcap.bt.files.btcpp_conditions import take_conditions, wrap
from btcap.bt.files.btcpp_nodes import STANDARD, UNSUPPORTED, V3_NAMES, MappingError
from btcap.bt.files.btcpp_rules import check_reactive
from btcap.bt.files.btcpp_scope import Ref, Scope
from btcap.bt.files.schema import NodeSpec, is_type_option
from btcap.bt.files.xmlread import XmlElement
from btcap.bt.ports import Port
from btcap.bt.registry import NodeRegistry, RegistryError
from btcap.bt.scripting import parse

__all__ = ["BTCPP_BUILTINS", "KEY", "MODEL_KINDS", "ElementReader", "Ref", "Scope", "literal"]

KEY = re.compile(r"^\{(.*)\}$")
_GENERIC = frozenset({"Action", "Condition", "Control", "Decorator"})
MODEL_KINDS = frozenset({*_GENERIC, "SubTree"})

#: Every node type BehaviorTree.CPP 4.x registers itself. Those not in
#: :data:`STANDARD` or :data:`UNSUPPORTED` are refused as "not mapped": such a file is
#: not using a custom type, so no node of the user's may stand in for it.
BTCPP_BUILTINS = frozenset(
    {
        *("AlwaysFailure", "AlwaysSuccess", "AsyncFallback", "AsyncSequence", "Delay"),
        *("Fallback", "ForceFailure"),
        *("ForceSuccess", "IfThenElse", "Inverter", "KeepRunningUntilFailure"),
        *("LoopBool", "LoopDouble", "LoopInt", "LoopString", "ManualSelector"),
        *("Parallel", "ParallelAll", "Precondition", "ReactiveFallback"),
        *("ReactiveSequence", "Repeat", "RetryUntilSuccessful", "RunOnce", "Script"),
        *("ScriptCondition", "Sequence", "SequenceWithMemory", "SetBlackboard"),
        *("SkipUnlessUpdated", "Sleep", "SubTree", "Switch2", "Switch3", "Switch4"),
        *("Switch5", "Switch6", "Timeout", "TryCatch", "UnsetBlackboard"),
        *("WaitValueUpdate", "WasEntryUpdated", "WhileDoElse"),
    }
)

#: The options of BehaviorTree.CPP's nodes that hold scripts.
_SCRIPT_OPTIONS = {"Script": ("code",), "ScriptCondition": ("code",), "Precondition": ("if",)}

#: How many lines an unknown-type message lists before "...".
_FIRST_LINES = 5


def literal(text: str, tp: Any) -> Any:
    """A literal attribute as a value of ``tp``; the builder checks what comes out."""
    if tp is Any or tp is str or tp is object:
        return text
    args = typing.get_args(tp)
    if str in args:
        return text
    origin = typing.get_origin(tp) or tp
    if origin in (list, tuple, set, frozenset):
        parts = [p.strip() for p in text.split(";")] if text.strip() else []
        if origin is tuple and args and args[-1] is not Ellipsis and len(args) == len(parts):
            return [literal(p, a) for p, a in zip(parts, args, strict=True)]
        return [literal(p, args[0] if args else Any) for p in parts]
    return _scalar(text)


def _near(word: str, registry: NodeRegistry) -> str:
    """' (did you mean X?)' among the types an XML element may name (v3's renamed)."""
    if word in V3_NAMES:
        return f" (BehaviorTree.CPP v3's name; v4 calls it {V3_NAMES[word]})"
    names = [n for n in registry if not n.startswith("user.") and registry.xml_type(n) is not None]
    names += STANDARD
    near = difflib.get_close_matches(word, names, n=3, cutoff=0.7)
    return f" (did you mean {', '.join(near)}?)" if near else ""


def _scalar(text: str) -> Any:
    """A number or boolean as BehaviorTree.CPP spells it; anything else stays text."""
    value = text.strip()
    for number in (int, float):
        try:
            return number(value)
        except ValueError:
            pass
    if value.lower() in ("true", "false"):
        return value.lower() == "true"
    return text


#: Builds a ``<SubTree>`` element: (element, its attributes, name, path, scope).
SubtreeReader = Callable[[XmlElement, dict[str, str], str, str, "Scope"], NodeSpec | None]


class ElementReader:
    """Reads node elements, reporting problems with their line into a shared list."""

    def __init__(
        self,
        where: str,
        registry: NodeRegistry,
        models: dict[str, XmlElement],
        subtree: SubtreeReader,
    ) -> None:
        self.where = where
        self.registry = registry
        self.models = models
        self.subtree = subtree
        self.problems: list[str] = []
        #: (BehaviorTree ID, node path) -> line of its element.
        self.node_lines: dict[tuple[str, str], int] = {}
        #: Unknown node type -> (file, line) of each element using it, reported once.
        self.unknown: dict[str, list[tuple[str, int]]] = {}
        #: The model of each type once its first use checked it (for the unknown report).
        self.seen_models: dict[str, XmlElement] = {}

    def fail(self, line: int, msg: str, where: str = "") -> None:
        self.problems.append(f"{where or self.where}: line {line}: {msg}")

    def unknown_problems(self) -> list[str]:
        """One line per unknown type (how often, where first), then what to do, once."""
        out = []
        declared = undeclared = 0
        for kind, uses in self.unknown.items():
            uses.sort()
            where, first = uses[0]
            lines = ", ".join(str(line) for _, line in uses[:_FIRST_LINES])
            more = ", ..." if len(uses) > _FIRST_LINES else ""
            n = f"{len(uses)} elements, lines" if len(uses) > 1 else "1 element, line"
            model = self.models.get(kind) or self.seen_models.get(kind)
            said = ""
            if model is not None:
                declared += 1
                said = f"; <TreeNodesModel> declares it (line {model.line})"
            else:
                undeclared += 1
            out.append(
                f"{where}: line {first}: <{kind}>: unknown node type {kind!r}"
                f"{_near(kind, self.registry)} ({n} {lines}{more}){said}"
            )
        if not out:
            return out
        todo = "register it (--load MODULE) or declare a capability interface of that name "
        todo += "(--interfaces FILE)"
        if declared:
            todo += ", or add --stub-missing to build a stand-in from <TreeNodesModel>"
        if undeclared:
            todo += ", or declare it in <TreeNodesModel> (or --model FILE) and add --stub-missing"
        if len(out) == 1:
            return [f"{out[0]}: {todo}"]
        its = todo.replace(" it ", " them ").replace(
            "a capability interface of that name", "capability interfaces of those names"
        )
        return [*out, f"{self.where}: {len(out)} unknown node types: {its}"]

    def node(
        self, el: XmlElement, parent: str | None, scope: Scope, taken: set[str]
    ) -> NodeSpec | None:
        attrs = dict(el.attrs)
        kind = el.tag
        if kind in _GENERIC:
            kind = attrs.pop("ID", "")
            if not kind:
                self.fail(el.line, f"<{el.tag}> without an ID naming its node type")
                return None
        conditions = take_conditions(el, attrs, self.fail)
        default = attrs.get("ID") or kind.rsplit(".", 1)[-1]  # acme.Grasp: Grasp
        name = self._name(attrs.pop("name", "") or default, el, taken)
        if name is None:
            return None
        path = name if parent is None else f"{parent}/{name}"
        self.node_lines[(scope.tree, path)] = el.line
        if not conditions:
            return self._build(el, attrs, kind, name, path, scope)
        for code in conditions.values():
            scope.add_script(parse(code), path, el.line, self.registry.script_enums)
        self.node_lines[(scope.tree, f"{path}/{name}")] = el.line
        inner = self._build(el, attrs, kind, name, f"{path}/{name}", scope)
        return wrap(inner, name, conditions)

    def _build(
        self, el: XmlElement, attrs: dict[str, str], kind: str, name: str, path: str, scope: Scope
    ) -> NodeSpec | None:
        if kind == "SubTree":
            return self.subtree(el, attrs, name, path, scope)
        kids: list[NodeSpec] = []
        names: set[str] = set()
        for child in el.children:
            spec = self.node(child, path, scope, names)
            if spec is not None:
                kids.append(spec)
        if kind in UNSUPPORTED:
            self.fail(
                el.line,
                f"<{el.tag}>: BehaviorTree.CPP's {kind} has no btcap equivalent: "
                f"{UNSUPPORTED[kind]}",
            )
            return None
        if kind == "SetBlackboard":
            return self._set_blackboard(el, attrs, name, path, scope)
        options: dict[str, Any] = {}
        std = STANDARD.get(kind)
        if std is not None:
            check_reactive(el, kind, self.fail)
            options = self._standard(el, attrs, kind)
            btcap = std.from_input if attrs else std.btcap
            spec = self._ports(el, attrs, btcap, name, path, scope, options, kind)
            for code in (options.get(k) for k in _SCRIPT_OPTIONS.get(kind, ())):
                if code is not None:
                    scope.add_script(parse(code), path, el.line, self.registry.script_enums)
        elif kind in BTCPP_BUILTINS:
            self.fail(
                el.line,
                f"<{el.tag}>: BehaviorTree.CPP's built-in {kind} is not mapped to a btcap "
                f"node (yet), and a node of your own may not stand in for a built-in",
            )
            return None
        else:
            found = self.registry.xml_type(kind)
            if found is None:
                self.unknown.setdefault(kind, []).append((self.where, el.line))
                scope.unsure.update(m[1] for m in map(KEY.match, attrs.values()) if m)
                return None
            spec = self._ports(el, attrs, found, name, path, scope, options, kind)
        if spec is not None:
            spec.children = kids
        return spec

    def _name(self, base: str, el: XmlElement, taken: set[str]) -> str | None:
        if not base:
            self.fail(el.line, f"<{el.tag}> name {base!r}: btcap node names cannot be empty")
            return None
        base = base.replace("/", "_").replace(".", "_")  # they separate btcap's paths
        name, k = base, 2
        while name in taken:  # BehaviorTree.CPP allows equal sibling names, btcap does not
            name, k = f"{base}_{k}", k + 1
        taken.add(name)
        return name

    def _standard(self, el: XmlElement, attrs: dict[str, str], kind: str) -> dict[str, Any]:
        std = STANDARD[kind]
        options = dict(std.fixed)
        entries: dict[str, str] = {}
        for key in std.required:
            if key not in attrs:
                why = f": {std.why_required}" if std.why_required else ""
                self.fail(el.line, f"<{el.tag}> needs attribute {key!r}{why}")
        for key, (option, convert) in std.attrs.items():
            if key not in attrs:
                continue
            text = attrs.pop(key)
            if KEY.match(text):
                if std.from_input:  # read as BehaviorTree.CPP reads it (read_options)
                    entries[key] = text
                    continue
                self.fail(
                    el.line,
                    f"<{el.tag}> attribute {key!r}={text!r}: btcap takes this "
                    f"as a fixed option, not from the blackboard",
                )
                continue
            try:
                value = convert(text)
            except MappingError as exc:
                self.fail(el.line, f"<{el.tag}> attribute {key!r}: {exc}")
                continue
            if value is not None:
                options[option] = value
        for key in attrs:
            known = ", ".join(std.attrs) or "none"
            self.fail(el.line, f"<{el.tag}> has no attribute {key!r} (attributes: {known})")
        attrs.clear()
        attrs.update(entries)  # the ports of std.from_input
        return options

    def _ports(
        self,
        el: XmlElement,
        attrs: dict[str, str],
        kind: str,
        name: str,
        path: str,
        scope: Scope,
        options: dict[str, Any],
        xml_name: str,
    ) -> NodeSpec | None:
        cls = self.registry.get(kind)
        probe: dict[str, Any] = dict(options)
        given: dict[str, str] = {}
        for key in cls.OPTIONS:
            if key in attrs:
                text = given[key] = attrs.pop(key)
                if KEY.match(text):
                    self.fail(
                        el.line,
                        f"<{el.tag}> {key}={text!r}: {kind}'s {key!r} is an "
                        f"option, set once when the tree is built, not a blackboard port",
                    )
                    del given[key]
        # An Any-typed option takes the type a type option names (a Constant's value).
        named = Any
        for key, text in given.items():
            if is_type_option(cls, key, cls.OPTIONS[key]):
                options[key] = text
                probe[key] = named = self._parse_type(text)
        for key, text in given.items():
            port = cls.OPTIONS[key]
            if not is_type_option(cls, key, port):
                tp = named if port.type is Any else port.type
                options[key] = probe[key] = literal(text, tp)
        try:  # ports may depend on options (a Constant's type, a bridge's interface)
            node = cls("probe", **probe)
            ins, outs = node.input_ports, node.output_ports
        except Exception:  # the builder reports it, naming the node
            ins, outs = cls.INPUTS, cls.OUTPUTS
        self._check_model(xml_name, cls.OPTIONS, ins, outs)
        inputs: dict[str, Any] = {}
        for key, text in attrs.items():
            if key in ins:
                entry = self.entry(text, key, el, reading=True)
                if entry is None:
                    inputs[key] = literal(text, ins[key].type)
                elif entry:
                    scope.readers.setdefault(entry, []).append(
                        Ref(path, key, el.line, ins[key].type)
                    )
            elif key in outs:
                entry = self.entry(text, key, el, reading=False)
                if entry:
                    scope.writers.setdefault(entry, []).append(
                        Ref(path, key, el.line, outs[key].type)
                    )
            else:
                self.fail(
                    el.line,
                    f"<{el.tag}>: {xml_name} has no port {key!r} (inputs: "
                    f"{', '.join(ins) or 'none'}; outputs: {', '.join(outs) or 'none'}; "
                    f"options: {', '.join(cls.OPTIONS) or 'none'})",
                )
        return NodeSpec(type=kind, name=name, options=options, inputs=inputs)

    def _parse_type(self, text: str) -> Any:
        try:
            return self.registry.parse_type(text)
        except RegistryError:
            return Any  # the builder reports the bad type name

    def _check_model(
        self, kind: str, opts: dict[str, Port], ins: dict[str, Port], outs: dict[str, Port]
    ) -> None:
        """A TreeNodesModel entry must agree with the registered node's ports."""
        model = self.models.pop(kind, None)  # checked once, at its first use
        if model is None:
            return
        self.seen_models[kind] = model
        where = model.where or self.where
        for port in model.children:
            key = port.attrs.get("name", "")
            if port.tag == "input_port" and key not in ins and key not in opts:
                have = ", ".join([*ins, *opts]) or "none"
                self.fail(
                    port.line,
                    f"<TreeNodesModel> {kind} input_port {key!r}: the btcap "
                    f"node type has no such input or option ({have})",
                    where,
                )
            elif port.tag == "output_port" and key not in outs:
                self.fail(
                    port.line,
                    f"<TreeNodesModel> {kind} output_port {key!r}: the btcap "
                    f"node type has no such output ({', '.join(outs) or 'none'})",
                    where,
                )
            elif port.tag == "inout_port":
                self.fail(
                    port.line,
                    f"<TreeNodesModel> {kind} inout_port {key!r}: btcap ports "
                    f"are inputs or outputs, not both",
                    where,
                )

    def entry(self, text: str, port: str, el: XmlElement, *, reading: bool) -> str | None:
        """The blackboard entry ``text`` names; None for a literal input, '' if refused."""
        m = KEY.match(text)
        if m is not None:
            inner = m.group(1)
        elif reading:
            return None
        else:
            inner = text  # an output names its entry with or without braces
        key = port if inner == "=" else inner
        if not key.removeprefix("@").isidentifier():  # {@key}: the root tree's entry
            self.fail(
                el.line,
                f"<{el.tag}> {port}={text!r}: blackboard names must be "
                f"identifiers here (they become port names of subtrees)",
            )
            return ""
        return key

    def _set_blackboard(
        self, el: XmlElement, attrs: dict[str, str], name: str, path: str, scope: Scope
    ) -> NodeSpec | None:
        value, target = attrs.pop("value", None), attrs.pop("output_key", None)
        for key in attrs:
            self.fail(el.line, f"<{el.tag}> has no attribute {key!r} (value, output_key)")
        if value is None or target is None:
            self.fail(el.line, f"<{el.tag}> needs both value and output_key")
            return None
        if KEY.match(value):
            self.fail(
                el.line,
                f"<{el.tag}> value={value!r}: copying one entry to another "
                f"is not supported; wire the writer of {value} to the readers instead",
            )
            return None
        entry = self.entry(target, "output_key", el, reading=False)
        if not entry:
            return None
        spec = NodeSpec(type="Constant", name=name, options={"value": value})
        scope.writers.setdefault(entry, []).append(Ref(path, "value", el.line, Any))
        scope.constants[entry] = (spec, value)
        return spec
