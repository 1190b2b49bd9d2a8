"""Random BehaviorTree.CPP scripts run in btcap and in BehaviorTree.CPP 4.8 (behaviortreepy).

A tree creates typed entries once (``i1 := 3``, ``d1 := 2.5``, ``s1 := 'ab'``…), then
runs random Script and ScriptCondition nodes (assignments with every operator, and
expressions over literals, entries and every operator family, mixed only through
parentheses, as the grammar wants). After every tick both blackboards must hold the
same values, written as BehaviorTree.CPP writes them (``std::to_string``: the kind of
each value shows), and the root must give the same result; a script that throws in
BehaviorTree.CPP must fail its node in btcap, and the comparison of that tree ends there.
"""

from __future__ import annotations

import random
from dataclasses import dataclass
from typing import Any

import behaviortreepy as bt

from btcap import State
from btcap.bt.files import loads_tree
from btcap.bt.registry import default_registry
from btcap.bt.scripting.values import to_text

INTS, REALS, TEXTS = ("i1", "i2"), ("d1", "d2"), ("s1", "s2")
KEYS = (*INTS, *REALS, *TEXTS)
_STRINGS = ("'ab'", "'2'", "'2.5'", "'true'", "''", '"x"', "'-3'")
_FAMILIES = {"math": ("+", "-", "*", "/"), "bit": ("&", "|", "^"), "concat": ("..",)}
_PREFIX = {"math": ("-",), "bit": ("~", "!"), "concat": ()}


def _literal(rng: random.Random) -> str:
    roll = rng.random()
    if roll < 0.3:
        return str(rng.choice((0, 1, 2, 3, 7, 10)))
    if roll < 0.35:
        return rng.choice(("+4", "0x1F", "true", "false"))
    if roll < 0.55:
        return rng.choice(("0.5", "2.5", "1.0", "3e2", "1.5e-1"))
    return rng.choice(_STRINGS)


def _atom(rng: random.Random, depth: int, fam: str) -> str:
    """Mostly what the family's operators take (numbers, or strings for ``..``)."""
    roll = rng.random()
    if depth > 0 and roll < 0.15:
        return f"({expression(rng, depth - 1)})"
    if rng.random() < 0.05:  # anything, so that conversions and errors are compared too
        return rng.choice(KEYS) if roll < 0.6 else _literal(rng)
    if fam == "concat":
        return rng.choice((*TEXTS, *_STRINGS, *INTS, *REALS, "2", "2.5"))
    if roll < 0.6:
        return rng.choice((*INTS, *REALS) if fam == "math" else INTS)
    return _literal(rng) if fam == "math" else rng.choice(("0", "1", "3", "0x1F", "true"))


def _operand(rng: random.Random, depth: int, fam: str) -> str:
    """One family's operators over atoms (a prefix applies to one atom)."""
    parts = []
    for _ in range(rng.choice((1, 1, 2, 2, 3))):
        a = _atom(rng, depth, fam)
        if _PREFIX[fam] and rng.random() < 0.2:
            a = rng.choice(_PREFIX[fam]) + a
        parts.append(a)
    out = parts[0]
    for p in parts[1:]:
        out += f" {rng.choice(_FAMILIES[fam])} {p}"
    return out


def expression(rng: random.Random, depth: int = 1) -> str:
    """A random expression: comparisons (chained), &&/||, perhaps a conditional; one
    operator family per expression (nine in ten), as the grammar wants."""
    fam = rng.choice(tuple(_FAMILIES))
    if rng.random() < 0.1:
        fam = ""  # mixes families: both must refuse it

    def comparison() -> str:
        out = _operand(rng, depth, fam or rng.choice(tuple(_FAMILIES)))
        for _ in range(rng.choice((0, 0, 0, 1, 1, 2))):
            rhs = _operand(rng, depth, fam or rng.choice(tuple(_FAMILIES)))
            out += f" {rng.choice(('==', '!=', '<', '>', '<=', '>='))} {rhs}"
        return out

    def logical() -> str:
        out = comparison()
        for _ in range(rng.choice((0, 0, 0, 1))):
            out += f" {rng.choice(('&&', '||'))} {comparison()}"
        return out

    if depth > 0 and rng.random() < 0.15:
        return f"{logical()} ? {expression(rng, depth - 1)} : {logical()}"
    return logical()


def _typed(rng: random.Random, kind: str, depth: int = 1) -> str:
    """An expression that gives a value of ``kind`` without error (mostly): integral
    numbers for ``int``, numbers for ``double``, text for ``string``, 0/1 for ``bool``."""
    if depth > 0 and rng.random() < 0.15:
        c = _typed(rng, "bool", 0)
        return f"{c} ? {_typed(rng, kind, depth - 1)} : {_typed(rng, kind, 0)}"
    if kind == "int":
        atoms = (*INTS, "0", "1", "2", "7", "0x1F", "+4", "true")
        ops = rng.choice((("+", "-", "*"), ("&", "|", "^")))
    elif kind == "double":
        atoms = (*INTS, *REALS, "0.5", "2.5", "3e2", "1.5e-1", "2")
        ops = ("+", "-", "*", "/")
    elif kind == "string":
        atoms = (*TEXTS, *INTS, *REALS, *_STRINGS)
        ops = ("..",)
    else:  # a comparison, perhaps two joined by && or ||
        num = "double" if rng.random() < 0.5 else "string"
        out = f"{_typed(rng, num, 0)} {rng.choice(('==', '!=', '<', '>', '<=', '>='))} "
        out += _typed(rng, num, 0)
        if depth > 0 and rng.random() < 0.3:
            out = f"({out}) {rng.choice(('&&', '||'))} ({_typed(rng, 'bool', 0)})"
        return out
    parts = [rng.choice(atoms) for _ in range(rng.choice((1, 2, 2, 3)))]
    if kind == "string" and all(p in (*INTS, *REALS) for p in parts):
        parts.append(rng.choice(TEXTS))
    out = parts[0]
    for p in parts[1:]:
        out += f" {rng.choice(ops)} {p}"
    if kind == "double" and rng.random() < 0.2:
        out = f"-({out})"
    return out


_KIND = {**dict.fromkeys(INTS, "int"), **dict.fromkeys(REALS, "double")}


def statement(rng: random.Random) -> str:
    """An assignment or an expression; one in five is anything the grammar allows."""
    if rng.random() < 0.2:
        key = rng.choice(KEYS)
        if rng.random() < 0.75:
            op = rng.choice((":=", "=", "=", "+=", "-=", "*=", "/=", "+="))
            return f"{key} {op} {expression(rng)}"
        return expression(rng)
    key = rng.choice(KEYS)
    kind = _KIND.get(key, "string")
    if kind == "string":
        return f"{key} {rng.choice((':=', '=', '+='))} {_typed(rng, 'string')}"
    op = rng.choice((":=", "=", "+=", "-=", "*=") + (("/=",) if kind == "double" else ()))
    return f"{key} {op} {_typed(rng, kind)}"


def conditions(rng: random.Random) -> str:
    """Random pre/post-condition attributes (BehaviorTree.CPP's _failureIf and others)."""
    out = ""
    for attr in ("_failureIf", "_successIf", "_onSuccess", "_onFailure", "_post"):
        if rng.random() < 0.35:
            code = _typed(rng, "bool", 0) if attr.endswith("If") else statement(rng)
            out += f' {attr}="{_attr(code)}"'
    return out


def _attr(text: str) -> str:
    return (
        text.replace("&", "&amp;").replace("<", "&lt;").replace('"', "&quot;")
        .replace("'", "&apos;")
    )  # fmt: skip


@dataclass
class ScriptTree:
    xml: str
    codes: list[str]


def random_script_tree(rng: random.Random, nodes: int = 4) -> ScriptTree:
    init = "; ".join(
        [f"{k} := {rng.choice((0, 1, 2, 5, -3))}" for k in INTS]
        + [f"{k} := {rng.choice(('0.5', '2.0', '-1.5', '4.25'))}" for k in REALS]
        + [f"{k} := {rng.choice(_STRINGS)}" for k in TEXTS]
    )
    body, codes = [], [init]
    for _ in range(nodes):
        if rng.random() < 0.7:
            code = "; ".join(statement(rng) for _ in range(rng.randint(1, 3)))
            el = f'<Script code="{_attr(code)}"/>'
        else:
            code = expression(rng) if rng.random() < 0.2 else _typed(rng, "bool")
            el = f'<ScriptCondition code="{_attr(code)}"/>'
        if rng.random() < 0.4:
            el = el.replace("/>", f"{conditions(rng)}/>")
        if rng.random() < 0.15:
            guard = _attr(_typed(rng, "bool", 0))
            other = rng.choice(("SUCCESS", "FAILURE"))
            el = f'<Precondition if="{guard}" else="{other}">{el}</Precondition>'
        if rng.random() < 0.5:
            el = f"<ForceSuccess>{el}</ForceSuccess>"
        body.append(el)
        codes.append(code)
    xml = (
        '<root BTCPP_format="4"><BehaviorTree ID="Main"><Sequence>'
        f'<RunOnce then_skip="false"><Script code="{_attr(init)}"/></RunOnce>'
        f"{''.join(body)}</Sequence></BehaviorTree></root>"
    )
    return ScriptTree(xml, codes)


def btcpp_values(tree: Any) -> dict[str, str]:
    board = tree.root_blackboard()
    return {k: board.get_string(k) for k in board.get_keys() if k in KEYS}


def btcap_values(tree: Any) -> dict[str, str]:
    return {k: to_text(v) for k, v in tree.blackboard.outputs.items() if v is not None}


_RESULT = {bt.NodeStatus.SUCCESS: "S", bt.NodeStatus.FAILURE: "F"}


@dataclass
class ScriptOutcome:
    ticks: int
    error: str | None  # the script error BehaviorTree.CPP threw, ending the comparison
    mismatch: str | None


def compare_scripts(t: ScriptTree, ticks: int = 3) -> ScriptOutcome:
    """Tick both ``ticks`` times; the first difference, if any."""
    factory = bt.BehaviorTreeFactory()
    try:
        theirs = factory.create_tree_from_text(t.xml)
    # BehaviorTree.CPP refuses a script while creating the tree (a literal std::stod
    # cannot hold throws std::out_of_range, which the bindings raise as IndexError)
    except (RuntimeError, IndexError) as exc:
        try:
            loads_tree(t.xml, "xml", default_registry(plugins=False))
        except Exception:
            return ScriptOutcome(0, "refused by both", None)
        return ScriptOutcome(0, None, f"BehaviorTree.CPP refused, btcap loaded: {exc}\n{t.xml}")
    mine = loads_tree(t.xml, "xml", default_registry(plugins=False))
    for n in range(ticks):
        state = mine.tick()
        failed = [x for x in mine.root.walk() if x.state is State.ERROR]
        try:
            want = _RESULT[theirs.tick_exactly_once()]
        except RuntimeError as exc:
            if not failed:
                return ScriptOutcome(
                    n, None, f"tick {n}: BehaviorTree.CPP threw {exc}, btcap succeeded\n{t.xml}"
                )
            # The blackboards are not compared here: btcap's failed node may be under a
            # ForceSuccess that goes on, where BehaviorTree.CPP's exception ended the tick.
            return ScriptOutcome(n, str(exc).splitlines()[-1], None)
        got = {State.SUCCEEDED: "S", State.FAILED: "F"}.get(state, "E")
        if failed or got == "E":
            err = failed[0].error if failed else None
            return ScriptOutcome(
                n, None, f"tick {n}: btcap failed ({err}), BehaviorTree.CPP {want}\n{t.xml}"
            )
        a, b = btcap_values(mine), btcpp_values(theirs)
        if got != want or a != b:
            return ScriptOutcome(
                n, None, f"tick {n}: btcap {got} {a}\nBehaviorTree.CPP {want} {b}\n{t.xml}"
            )
    return ScriptOutcome(ticks, None, None)


# -- pre/post conditions on the node-level random trees ------------------------------------

_COUNTERS = ("s", "f", "p", "h")


def with_conditions(root: Any, rng: random.Random, skips: bool = False) -> Any:
    """``root`` (a :class:`btcpp_oracle.El`) with counters run by pre/post conditions on
    some of its nodes, under a Sequence that creates the counters once. ``skips`` adds
    ``_skipIf`` and ``_while`` over the counters (not on an IfThenElse's or WhileDoElse's
    condition: BehaviorTree.CPP throws when that one is skipped)."""
    from btcpp_oracle import El

    conditions = {
        id(el.children[0]) for el in root.walk() if el.tag in ("IfThenElse", "WhileDoElse")
    }
    for el in root.walk():
        if skips and el.tag == "RunOnce" and rng.random() < 0.5:
            del el.attrs["then_skip"]  # BehaviorTree.CPP's default: SKIPPED after its run
        if skips and id(el) not in conditions:
            if rng.random() < 0.2:
                el.attrs["_skipIf"] = f"{rng.choice('sfp')} == {rng.randint(0, 3)}"
            if rng.random() < 0.15:
                el.attrs["_while"] = f"{rng.choice('sfp')} < {rng.randint(1, 6)}"
        if rng.random() < 0.4:
            el.attrs["_onSuccess"] = "s += 1"
            el.attrs["_onFailure"] = "f += 1"
        if rng.random() < 0.3:
            el.attrs["_post"] = "p += 1"
        if el.tag in ("Act",) and rng.random() < 0.5:
            el.attrs["_onHalted"] = "h += 1"
        if rng.random() < 0.15:
            el.attrs["_failureIf"] = f"f > {rng.randint(0, 3)}"
        if rng.random() < 0.15:
            el.attrs["_successIf"] = f"s > {rng.randint(0, 3)}"
    init = El("Script", "init", {"code": "s := 0; f := 0; p := 0; h := 0"})
    return El("Sequence", "top", {}, [El("RunOnce", "once", {"then_skip": "false"}, [init]), root])


def _rechecked(mine: Any, before: dict[int, State]) -> bool:
    """Whether a node with pre-conditions was ticked after giving a result, by a parent
    that had not reset it in BehaviorTree.CPP: one still running (a reactive parent
    re-ticking an earlier child) or an IfThenElse/WhileDoElse (its condition keeps its
    status). BehaviorTree.CPP skips the pre-conditions then (the node's status is not
    IDLE); btcap checks them whenever the node is not running (documented)."""
    from btcap.bt.async_nodes import LatchedIfThenElse
    from btcap.bt.composites import IfThenElse
    from btcap.bt.scripting.nodes import ScriptConditions

    for n in mine.tree.root.walk():
        parent = n.parent_node
        if isinstance(n, ScriptConditions) and n._pre and parent is not None:
            if before.get(id(n)) not in (State.SUCCEEDED, State.FAILED) or n.state is State.IDLE:
                continue
            if before.get(id(parent)) in _ACTIVE_STATES or isinstance(
                parent, (IfThenElse, LatchedIfThenElse)
            ):
                return True
    return False


def _condition_skipped(mine: Any) -> bool:
    """Whether an IfThenElse or WhileDoElse failed on a skipped condition in this tick."""
    return any(
        n.state is State.ERROR and "its condition was skipped" in str(n.error)
        for n in mine.tree.root.walk()
    )


_ACTIVE_STATES = (State.RUNNING, State.ASSIGNED, State.UNASSIGNED)


def compare_conditions(root: Any, ticks: int = 10, once: bool = False) -> ScriptOutcome:
    """:func:`btcpp_oracle.compare` with the counters compared after every tick and halt
    (``once``: ticked by ``tickOnce``, else ``tickExactlyOnce``)."""
    from btcpp_oracle import WAKES_FOREVER, BtcapRun, BtcppRun, WakingForever, document, scripts_of

    xml = document(root)
    scripts = scripts_of(root)
    try:
        theirs = BtcppRun(xml, scripts, once)
    except RuntimeError:
        return ScriptOutcome(0, "refused by BehaviorTree.CPP", None)
    # The counters exist before the first tick: if the comparison stops before
    # BehaviorTree.CPP's first tick, its Tree halts every node when destroyed, and an
    # _onHalted on an entry that does not exist throws there (std::terminate).
    for key in _COUNTERS:
        theirs.tree.root_blackboard().set_int(key, 0)
    mine = BtcapRun(xml, scripts, once)

    def counters() -> tuple[dict[str, str], dict[str, str]]:
        board = theirs.tree.root_blackboard()
        a = {k: to_text(v) for k, v in mine.tree.blackboard.outputs.items() if v is not None}
        return a, {k: board.get_string(k) for k in board.get_keys() if k in _COUNTERS}

    # Checked on every root tick: tickOnce makes several, and a node that finished in one
    # may be re-checked in the next.
    rechecked = []
    root_tick = mine.tree.tick

    def checked_root_tick() -> State:
        before = {id(n): n.state for n in mine.tree.root.walk()}
        state: State = root_tick()
        if _rechecked(mine, before):
            rechecked.append(True)
        return state

    mine.tree.tick = checked_root_tick
    for t in range(ticks):
        try:
            got = mine.tick()
        except WakingForever:
            return ScriptOutcome(t, WAKES_FOREVER, None)
        if rechecked:
            return ScriptOutcome(t, "conditions_checked_when_idle", None)
        if _condition_skipped(mine):  # BehaviorTree.CPP throws, or ticks an IDLE root forever
            return ScriptOutcome(t, "skipped_condition", None)
        if mine.now:  # before BehaviorTree.CPP's tick, which may throw then (as compare)
            return ScriptOutcome(t, sorted(mine.now)[0], None)
        want = theirs.tick()
        a, b = counters()
        if got != want or a != b:
            return ScriptOutcome(t, None, f"tick {t}: btcap {got} {a}\nBT.CPP {want} {b}\n{xml}")
        if mine.later:
            return ScriptOutcome(t + 1, sorted(mine.later)[0], None)
    mine.halt()
    theirs.halt()
    # BehaviorTree.CPP's haltTree runs every node's _onHalted, running or not (documented);
    # a parent halting a running child was compared above, tick by tick.
    a, b = counters()
    a.pop("h", None), b.pop("h", None)
    if a != b:
        return ScriptOutcome(ticks, None, f"halt: btcap {a} BT.CPP {b}\n{xml}")
    return ScriptOutcome(ticks, None, None)
