"""Stand-ins for the node types a BehaviorTree.CPP file declares but nobody registered.

With ``stub_missing`` (``btcap tree validate|run --stub-missing``) every type that a
``<TreeNodesModel>`` declares (in the file, an included file or ``--model FILE``) and
that is neither registered nor one of BehaviorTree.CPP's built-ins is built from its
model, with its ports, much as BehaviorTree.CPP's substitution rules put a
``TestNode`` in its place:

- an ``<Action>`` or ``<Condition>`` returns a scripted result, SUCCESS by default;
- Nav2's control and decorator nodes (``RecoveryNode``, ``PipelineSequence``,
  ``RoundRobin``, ``RateController``, ``SingleTrigger``) decide as Nav2's own
  (:mod:`btcap.bt.nav2_nodes`);
- any other ``<Decorator>`` returns its child's result and any other ``<Control>`` ticks
  its children as a ``Sequence`` does; the load warns about every such control and
  Nav2's other decorators (:func:`stand_in_note`): a flow stood in for changes what the
  tree does.

A type no model declares is stubbed from its use (:func:`infer_models`). Port types
are read from the model where it gives them (``double``, ``int``, ``bool``,
``std::string`` and their kin); any other C++ type is untyped. Inputs are optional
(BehaviorTree.CPP reads them only when the node asks). The script is a small YAML file
(or the same content as a dict)::

    default: SUCCESS                          # every stubbed action and condition
    types:                                    # by node type
      ComputePathToPose: [RUNNING, SUCCESS]   # one result per tick, the last repeats
      GoalUpdated: FAILURE
    names:                                    # by node name or path (* and ? wildcards);
      "Follow*":                              # first match wins, before the type's script
        results: [RUNNING, RUNNING, SUCCESS]
        outputs: {error_code_id: 0}           # written when a result is SUCCESS/FAILURE

A run starts the script over each time the node finishes or is reset.
"""

from __future__ import annotations

import dataclasses
import fnmatch
import os
from collections.abc import Callable, Collection, Iterable, Mapping
from pathlib import Path
from typing import Any, ClassVar

from btcap.bt.composites import Sequence
from btcap.bt.decorators import Remap
from btcap.bt.files.btcpp_elements import BTCPP_BUILTINS, KEY, MODEL_KINDS, literal
from btcap.bt.files.btcpp_nodes import UNSUPPORTED
from btcap.bt.files.parse import decode, read_bytes
from btcap.bt.files.schema import TreeFileError
from btcap.bt.files.xmlread import XmlElement
from btcap.bt.nav2_nodes import NAV2_NODES, NAV2_STOOD_IN
from btcap.bt.node import Leaf, Node
from btcap.bt.ports import Port
from btcap.bt.registry import NodeRegistry, RegistryError
from btcap.bt.state import DONE, State, TreeError

__all__ = [
    "StubScripts",
    "cpp_type",
    "infer_models",
    "load_scripts",
    "make_stub",
    "stand_in_note",
    "stub_notes",
    "stub_registry",
]

_CPP: dict[str, Any] = {
    "bool": bool,
    **dict.fromkeys(("double", "float", "long double"), float),
    **dict.fromkeys(("std::string", "string", "std::basic_string<char>", "BT::StringView"), str),
    **dict.fromkeys(
        (
            *("int", "unsigned", "unsigned int", "long", "unsigned long", "short", "char"),
            *("long long", "unsigned long long", "size_t", "std::size_t", "unsigned short"),
            *(f"{s}int{n}_t" for s in ("", "u", "std::", "std::u") for n in (8, 16, 32, 64)),
        ),
        int,
    ),
}

_STATES = {
    "SUCCESS": State.SUCCEEDED,
    "SUCCEEDED": State.SUCCEEDED,
    "FAILURE": State.FAILED,
    "FAILED": State.FAILED,
    "RUNNING": State.RUNNING,
}


def cpp_type(text: str | None) -> Any:
    """The port type a model's C++ type names; Any for the ones btcap cannot know."""
    if text is None:
        return Any
    name = " ".join(text.split())
    if name.startswith(("std::__cxx11::basic_string<char", "std::basic_string<char")):
        return str  # what typeid demangles std::string to, as Groot2 may save it
    return _CPP.get(name, Any)


@dataclasses.dataclass(frozen=True)
class Script:
    """What a stubbed leaf returns, tick by tick, and writes when it finishes."""

    results: tuple[State, ...] = (State.SUCCEEDED,)
    outputs: Mapping[str, Any] = dataclasses.field(default_factory=dict)


@dataclasses.dataclass(frozen=True)
class StubScripts:
    """The scripts of a run: by name pattern first, then by type, then the default."""

    default: Script = Script()
    types: Mapping[str, Script] = dataclasses.field(default_factory=dict)
    names: tuple[tuple[str, Script], ...] = ()

    def find(self, kind: str, name: str, path: str = "") -> Script:
        """By name or node path (as BehaviorTree.CPP's filters), then type, then default."""
        for pattern, script in self.names:
            if fnmatch.fnmatchcase(name, pattern) or fnmatch.fnmatchcase(path, pattern):
                return script
        return self.types.get(kind, self.default)


def load_scripts(src: str | os.PathLike[str] | Mapping[str, Any] | None) -> StubScripts:
    """Read a script file (or its content); problems name the file and the field."""
    if src is None:
        return StubScripts()
    if isinstance(src, Mapping):
        raw: Any = src
        where = "stub script"
    else:
        where = str(src)
        raw = decode(read_bytes(Path(src)), "yaml", where)
    problems: list[str] = []
    if not isinstance(raw, Mapping):
        raise TreeFileError([f"{where}: expected a mapping of default, types and names"])
    for key in raw:
        if key not in ("default", "types", "names"):
            problems.append(f"{where}: {key!r}: expected default, types or names")
    default = _script(raw.get("default", "SUCCESS"), f"{where}: default", problems)
    parts: dict[str, dict[str, Script]] = {}
    for part in ("types", "names"):
        table = raw.get(part) or {}
        if not isinstance(table, Mapping):
            problems.append(f"{where}: {part}: expected a mapping of name to script")
            table = {}
        parts[part] = {
            str(k): _script(v, f"{where}: {part}.{k}", problems) for k, v in table.items()
        }
    if problems:
        raise TreeFileError(problems)
    return StubScripts(default, parts["types"], tuple(parts["names"].items()))


def _script(raw: Any, where: str, problems: list[str]) -> Script:
    outputs: Any = {}
    if isinstance(raw, Mapping):
        extra = set(raw) - {"results", "outputs"}
        if extra:
            problems.append(f"{where}: {sorted(extra)[0]!r}: expected results or outputs")
        outputs = raw.get("outputs") or {}
        if not isinstance(outputs, Mapping):
            problems.append(f"{where}.outputs: expected a mapping of output port to value")
            outputs = {}
        raw = raw.get("results", "SUCCESS")
    items = raw if isinstance(raw, list) else [raw]
    results = []
    for item in items:
        state = _STATES.get(str(item).upper()) if isinstance(item, str) else None
        if state is None:
            problems.append(f"{where}: {item!r}: expected SUCCESS, FAILURE or RUNNING")
        else:
            results.append(state)
    if not items:
        problems.append(f"{where}: an empty list; expected at least one result")
    return Script(tuple(results) or (State.SUCCEEDED,), dict(outputs))


class StubLeaf(Leaf):
    """A stubbed ``<Action>`` or ``<Condition>``: returns its script's results."""

    __slots__ = ("_script", "_step")
    KIND: ClassVar[str] = ""
    SCRIPTS: ClassVar[StubScripts] = StubScripts()

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._step = 0
        self._script = self._checked(self.SCRIPTS.find(self.KIND, self.name))

    def _checked(self, script: Script) -> Script:
        for key in script.outputs:
            if key not in self.output_ports:
                have = ", ".join(self.output_ports) or "none"
                raise TreeError(
                    f"stub script for {self.KIND} {self.name!r}: output {key!r}: the model "
                    f"declares no such output port ({have})"
                )
        return script

    def on_setup(self) -> None:
        """A name pattern may also match the node's path, known once it is in a tree."""
        self._script = self._checked(self.SCRIPTS.find(self.KIND, self.name, self.path))

    def on_tick(self) -> State:
        results = self._script.results
        state = results[min(self._step, len(results) - 1)]
        if state in DONE:
            self._step = 0
            for key, value in self._script.outputs.items():
                self.outputs[key] = value
        else:
            self._step += 1
        return state

    def on_reset(self) -> None:
        self._step = 0


class StubDecorator(Remap):
    """A stubbed ``<Decorator>``: its child's result."""

    __slots__ = ()


class StubControl(Sequence):
    """A stubbed ``<Control>``: ticks its children as a Sequence."""

    __slots__ = ()


_BASES: dict[str, type[Node]] = {
    "Action": StubLeaf,
    "Condition": StubLeaf,
    "Decorator": StubDecorator,
    "Control": StubControl,
}


def _used_types(trees: Iterable[XmlElement]) -> set[str]:
    """The node types the ``trees`` use (element names, and ``ID`` of generic ones)."""
    found: set[str] = set()
    stack = [c for t in trees for c in t.children]
    while stack:
        el = stack.pop()
        stack.extend(el.children)
        found.add(el.attrs.get("ID", "") if el.tag in MODEL_KINDS else el.tag)
    return found


def infer_models(
    trees: Iterable[XmlElement], wanted: Callable[[str], bool]
) -> dict[str, XmlElement]:
    """Models of the ``wanted`` types no ``<TreeNodesModel>`` declares, from their uses.

    As BehaviorTree.CPP's tutorials ship no model: the kind is the element's
    (``<Action ID=...>``) or follows from the children (none: an Action, one: a
    Decorator, else a Control); every attribute used is an untyped input.
    """
    found: dict[str, XmlElement] = {}
    kids: dict[str, tuple[int, int]] = {}  # fewest and most children of a use
    stack = [c for t in trees for c in t.children]
    while stack:
        el = stack.pop()
        stack.extend(el.children)
        generic = el.tag in MODEL_KINDS and el.tag != "SubTree"
        kind = el.attrs.get("ID", "") if generic else el.tag
        if not kind or not wanted(kind):
            continue
        tag = el.tag if generic else ""
        model = found.setdefault(kind, XmlElement(tag, {"ID": kind}, el.line, where=el.where))
        if (el.where, el.line) < (model.where, model.line):
            model.line, model.where = el.line, el.where
        low, high = kids.get(kind, (len(el.children), len(el.children)))
        kids[kind] = (min(low, len(el.children)), max(high, len(el.children)))
        names = {p.attrs["name"] for p in model.children}
        for key in el.attrs:
            if key not in names and key not in ("ID", "name") and key.isidentifier():
                model.children.append(XmlElement("input_port", {"name": key}, el.line))
                names.add(key)
    found = dict(sorted(found.items(), key=lambda item: (item[1].where, item[1].line)))
    for kind, model in found.items():
        if not model.tag:
            low, high = kids[kind]
            model.tag = "Action" if high == 0 else "Decorator" if low == high == 1 else "Control"
    return found


def make_stub(model: XmlElement, scripts: StubScripts) -> type[Node]:
    """A node class with the ports ``model`` declares, standing in for its type."""
    kind = model.attrs["ID"]
    ins: dict[str, Port] = {}
    outs: dict[str, Port] = {}
    for port in model.children:
        name = port.attrs.get("name", "")
        if not name.isidentifier():
            continue  # the element reader reports an attribute no port takes
        tp = cpp_type(port.attrs.get("type"))
        optional = Any if tp is Any else tp | None
        if port.tag in ("input_port", "inout_port"):
            default = port.attrs.get("default")
            if default is not None and KEY.match(default):
                default = None  # a default entry: only a port given in the XML reads one
            ins[name] = Port(optional, None if default is None else literal(default, tp))
        if port.tag in ("output_port", "inout_port"):
            outs[name] = Port(optional)
    base = _BASES[model.tag]
    if model.tag in ("Control", "Decorator") and kind in NAV2_NODES:
        base = NAV2_NODES[kind]
        ins.update(base.INPUTS)  # Nav2's own ports, typed, with its defaults
    if base is not StubLeaf and (kind in scripts.types):
        raise TreeFileError(
            [
                f"stub script: types.{kind}: {kind} is a {model.tag}; scripts set what actions "
                f"and conditions return"
            ]
        )
    doc = f"Stand-in for {kind}, built from its <TreeNodesModel> {model.tag} (line {model.line})."
    if kind in NAV2_NODES:
        doc = f"Nav2's {kind}, with the ports of its <TreeNodesModel> (line {model.line})."
    return type(
        kind,
        (base,),
        {
            "__slots__": (),
            "__doc__": doc,
            "__module__": __name__,
            "INPUTS": ins,
            "OUTPUTS": outs,
            "KIND": kind,
            "SCRIPTS": scripts,
        },
    )


def stub_notes(kind: str | None, model: XmlElement, trees: Iterable[XmlElement]) -> list[str]:
    """What to tell of a stand-in: that it may decide otherwise than the node it stands for
    (:func:`stand_in_note`) and, for a ``kind`` declared in no model, what it was stubbed
    from (its use in a tree)."""
    notes = [note] if (note := stand_in_note(model, trees)) else []
    if kind is not None:
        ports = ", ".join(p.attrs["name"] for p in model.children) or "none"
        notes.append(
            f"{kind} is declared in no <TreeNodesModel>; stubbed from its use "
            f"({model.tag}; inputs: {ports})"
        )
    return notes


def stand_in_note(model: XmlElement, trees: Iterable[XmlElement]) -> str | None:
    """What a run must be told about the stand-in for ``model``'s type: any control, and
    Nav2's decorators btcap does not model (None for the others, for Nav2's own here, and
    for a type only declared: ``trees`` are checked for a use, unless empty)."""
    kind = model.attrs["ID"]
    if kind in NAV2_NODES or model.tag not in ("Control", "Decorator"):
        return None
    trees = list(trees)
    if trees and kind not in _used_types(trees):
        return None
    does = (
        "ticks its children as a Sequence"
        if model.tag == "Control"
        else ("returns its child's result")
    )
    if kind in NAV2_STOOD_IN:
        return (
            f"{kind} is Nav2's, and needs {NAV2_STOOD_IN[kind]}: its stand-in {does}, not as Nav2's"
        )
    if model.tag == "Decorator":
        return None
    return f"{kind} is a Control btcap does not know: its stand-in {does}"


def stub_registry(
    registry: NodeRegistry,
    models: dict[str, XmlElement],
    trees: Collection[XmlElement],
    script: str | os.PathLike[str] | Mapping[str, Any] | None,
    where: str,
    reports: tuple[list[str], list[str]],
    seen: dict[str, XmlElement],
) -> NodeRegistry | None:
    """A copy of ``registry`` with a stand-in for each type ``models`` declare and no
    registered type provides, and for each type used but neither known nor modelled.

    Problems and warnings go to ``reports``; a stubbed model moves to ``seen`` (its
    ports are its own). None if the stub script cannot be read.
    """
    problems, warnings = reports
    try:
        scripts = load_scripts(script)
    except TreeFileError as exc:
        problems.extend(exc.problems)
        return None
    registry = registry.copy()
    for kind, model in list(models.items()):
        if model.tag == "SubTree" or kind in BTCPP_BUILTINS or registry.xml_type(kind) is not None:
            continue
        try:
            registry.register(make_stub(model, scripts), kind)
        except (TreeFileError, RegistryError) as exc:
            problems.extend(exc.problems if isinstance(exc, TreeFileError) else [str(exc)])
            continue
        for note in stub_notes(None, model, trees):
            warnings.append(f"{model.where or where}: line {model.line}: {note}")
        seen[kind] = models.pop(kind)

    def unknown(kind: str) -> bool:
        """Neither BehaviorTree.CPP's, known nor modelled."""
        return not (
            kind in BTCPP_BUILTINS
            or kind in UNSUPPORTED
            or kind in models
            or registry.xml_type(kind) is not None
        )

    for kind, model in infer_models(trees, unknown).items():
        registry.register(make_stub(model, scripts), kind)
        for note in stub_notes(kind, model, ()):
            warnings.append(f"{model.where or where}: line {model.line}: {note}")
    return registry
