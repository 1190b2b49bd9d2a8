"""BehaviorTree.CPP 4.8 (behaviortreepy) against btcap on generated scripts and trees,
drawn by hypothesis over the whole grammar rather than from seeds: prefix chains, new
lines and tabs between tokens, literals at the edges of int64 and double, strings read
as numbers (hexadecimal floats included), assignments inside expressions; and trees with
pre/post conditions on any node, ``Precondition`` (every ``else``) and ``Script`` leaves.

The example counts are bounded and derandomized (the suite stays cheap and replayable);
``BTCAP_HYPOTHESIS_EXAMPLES`` raises them for a wide run. Each case in ``FOUND`` is a
difference these tests found, fixed since: each fails without its fix.
"""

from __future__ import annotations

import os
import random
import warnings

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from structlog.testing import capture_logs

pytest.importorskip(
    "behaviortreepy",
    reason="behaviortreepy (BehaviorTree.CPP 4.8) has wheels only for CPython 3.11 on x86-64 Linux",
)

import behaviortreepy as bt
import script_oracle
from btcpp_oracle import WAKES_FOREVER, El, random_tree

from btcap import State
from btcap.bt.files import TreeFileError, loads_tree
from btcap.bt.files.btcpp_nodes import DIFFERENCES
from btcap.bt.registry import default_registry
from btcap.bt.scripting.values import to_text

_WIDE = int(os.environ.get("BTCAP_HYPOTHESIS_EXAMPLES", "0"))


def _settings(examples: int) -> settings:
    return settings(
        max_examples=_WIDE or examples,
        derandomize=not _WIDE,
        deadline=None,
        database=None,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
    )


# -- scripts ---------------------------------------------------------------------------

_ENTRIES = ("i1", "i2", "d1", "d2", "s1", "s2")
_INTS = ("0", "1", "2", "7", "+4", "0x1F", "0X10", "00012")
_INTS_BAD = (
    "9007199254740991", "9007199254740992", "9007199254740993", "9223372036854775807",
    "9223372036854775808", "0x8000000000000000", "18446744073709551615",
)  # fmt: skip
_REALS = ("0.5", "2.5", "1.0", "3e2", "1E3", "1.5e-1", "1e308", "2.2250738585072014e-308")
_REALS_BAD = ("1.8e308", "1e400", "1e-310", "4.9e-324")
_TEXTS = (
    "'ab'", "'2'", "'2.5'", "'true'", "'false'", "''", '"x"', "'-3'", "' 12'", "'12abc'",
    "'0x10'", "'0x1p3'", "'-0x1.8p1'", "'0x'", "'1e5'", "'.5'", "'inf'", "'nan'", "'1e400'",
    "'1e-310'",
)  # fmt: skip
_PREFIX = {"math": ("-",), "bit": ("~", "!"), "concat": ()}
_BINARY = {"math": ("+", "-", "*", "/"), "bit": ("&", "|", "^"), "concat": ("..",)}
_BLANKS = st.sampled_from((" ", " ", " ", "", "\n", "\t", " \n  "))


@st.composite
def _atom(draw: st.DrawFn, depth: int, fam: str, wild: bool) -> str:
    """Mostly what ``fam`` takes; ``wild``: anything now and then (unknown entries,
    refused literals, strings in arithmetic), so that errors are compared too."""
    pick = draw(st.integers(0, 9))
    if depth > 0 and pick == 0:
        return f"({draw(_expression(depth - 1, wild, '' if wild else fam))})"
    if depth > 0 and pick == 1:  # an assignment inside an expression
        key = draw(st.sampled_from(_ENTRIES[:4] if fam != "concat" else _ENTRIES))
        return f"({key} {draw(st.sampled_from((':=', '=', '+=')))} {draw(_atom(0, fam, wild))})"
    if wild and draw(st.integers(0, 5)) == 0:
        return draw(st.sampled_from((*_INTS_BAD, *_REALS_BAD, *_TEXTS, "u1", "s1")))
    if pick < 5:
        if fam == "concat":
            return draw(st.sampled_from(_ENTRIES))
        return draw(st.sampled_from(("i1", "i2", "true", "false") + ("d1", "d2") * (fam == "math")))
    pool = _TEXTS + _INTS + _REALS if fam == "concat" else _INTS + _REALS
    return draw(st.sampled_from(pool if fam != "bit" else _INTS))


@st.composite
def _operand(draw: st.DrawFn, depth: int, fam: str, wild: bool) -> str:
    """One family's operators over atoms, each with up to three prefixes; now and then
    a prefix of another family (both must refuse it)."""
    blank = draw(_BLANKS)
    parts = []
    for _ in range(draw(st.integers(1, 3))):
        a = draw(_atom(depth, fam, wild))
        for _ in range(draw(st.sampled_from((0, 0, 0, 1, 1, 2, 3))) * bool(_PREFIX[fam])):
            a = draw(st.sampled_from(_PREFIX[fam])) + draw(st.sampled_from(("", "", " "))) + a
        if wild and draw(st.integers(0, 9)) == 0:
            a = draw(st.sampled_from(("-~", "!-", "~-"))) + a
        parts.append(a)
    out = parts[0]
    for p in parts[1:]:
        blank = blank or " " * (fam == "concat")  # 1..2 is refused by both: a number's suffix
        out += f"{blank}{draw(st.sampled_from(_BINARY[fam]))}{draw(_BLANKS)}{p}"
    return out


@st.composite
def _expression(draw: st.DrawFn, depth: int, wild: bool, fam: str = "") -> str:
    """``fam`` given: an expression of that family whose value is of its kind (no
    comparison or logic on top), as the entry it is assigned to wants."""
    mixed = wild and draw(st.integers(0, 4)) == 0  # families mixed: refused by both

    def family() -> str:
        return draw(st.sampled_from(tuple(_BINARY)))

    if fam:
        return draw(_operand(depth, fam, wild))
    fam = family()

    def comparison(needed: bool = False) -> str:
        out = draw(_operand(depth, family() if mixed else fam, wild))
        for _ in range(draw(st.sampled_from((1, 2) if needed else (0, 0, 1, 1, 2)))):
            op = draw(st.sampled_from(("==", "!=", "<", ">", "<=", ">=")))
            out += f"{draw(_BLANKS)}{op} {draw(_operand(depth, family() if mixed else fam, wild))}"
        return out

    logic = draw(st.sampled_from((0, 0, 1, 2)))
    out = comparison(bool(logic) and not wild)  # && and || want bools: comparisons
    for _ in range(logic):
        out += f" {draw(st.sampled_from(('&&', '||')))}{draw(_BLANKS)}{comparison(not wild)}"
    if depth > 0 and draw(st.integers(0, 5)) == 0:
        then = draw(_expression(depth - 1, wild))
        out = f"{out} ?{draw(_BLANKS)}{then} : {comparison()}"
    return out


#: The family whose values an entry of each kind takes (tame statements).
_KIND_FAMILY = {"i": ("bit",), "d": ("math", "bit"), "s": ("concat",)}


@st.composite
def _statement(draw: st.DrawFn, wild: bool) -> str:
    if draw(st.integers(0, 4)) == 0:
        return draw(_expression(1, wild))
    key = draw(st.sampled_from((*_ENTRIES, "u1") if wild else _ENTRIES))
    if wild or draw(st.integers(0, 3)) == 0:
        op = draw(st.sampled_from((":=", "=", "=", "+=", "-=", "*=", "/=")))
        return f"{draw(_BLANKS)}{key}{draw(_BLANKS)}{op} {draw(_expression(1, wild))}"
    fam = draw(st.sampled_from(_KIND_FAMILY[key[0]]))
    ops = (":=", "=", "+=") if key[0] == "s" else (":=", "=", "+=", "-=", "*=")
    op = draw(st.sampled_from(ops))
    return f"{draw(_BLANKS)}{key}{draw(_BLANKS)}{op} {draw(_expression(1, wild, fam))}"


def _attr(text: str) -> str:
    return script_oracle._attr(text).replace("\n", "&#10;").replace("\t", "&#9;")


@st.composite
def script_trees(draw: st.DrawFn) -> script_oracle.ScriptTree:
    rng = random.Random(draw(st.integers(0, 2**32)))
    init = script_oracle.random_script_tree(rng, 0).codes[0]  # i1 := 2; d1 := 0.5; ...
    body, codes = [], [init]
    wild = draw(st.integers(0, 3)) == 0  # errors and refusals (else: mostly values)
    for _ in range(draw(st.integers(1, 4))):
        code = ";".join(draw(st.lists(_statement(wild), min_size=1, max_size=2)))
        tag = draw(st.sampled_from(("Script", "Script", "ScriptCondition")))
        body.append(f'<ForceSuccess><{tag} code="{_attr(code)}"/></ForceSuccess>')
        codes.append(code)
    xml = (
        '<root BTCPP_format="4"><BehaviorTree ID="Main"><Sequence>'
        f'<RunOnce then_skip="false"><Script code="{_attr(init)}"/></RunOnce>'
        f"{''.join(body)}</Sequence></BehaviorTree></root>"
    )
    return script_oracle.ScriptTree(xml, codes)


@_settings(80)
@given(script_trees())
def test_generated_scripts_agree_with_behaviortree_cpp(t: script_oracle.ScriptTree) -> None:
    with capture_logs(), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = script_oracle.compare_scripts(t, ticks=2)
    assert out.mismatch is None, out.mismatch


#: Scripts btcap read differently from BehaviorTree.CPP 4.8 before this test: each is
#: run in both and must agree (result, values, refusal). Found by the strategies above.
FOUND = [
    "x := --3",  # repeated prefixes of one family: read by BehaviorTree.CPP
    "y := 2; x := - -y; z := !!1; w := ~!1; v := 1 & ~~2",
    "x := -~1",  # two families: refused by both
    "x := 9223372036854775808",  # beyond int64: refused
    "x := 0xFFFFFFFFFFFFFFFF",
    "x := 1.8e308",  # std::stod's out_of_range: refused
    "x := 1e-310",
    "x := 1;\ny := 2",  # a new line is a blank anywhere
    "\nx := 1 +\n 2\n",
    "x := '0x1p3' == 8; y := 1; y = '-0x1.8p1'",  # strtod's hexadecimal floats
    "i := 5; x := i + 9007199254740993",  # no double holds it: an error, right side too
    "x := 9007199254740993 & 1",
    "x := 9007199254740992 ? 1 : 2",
    "d := 0.5; d += (d := 5)",  # a compound assignment reads its entry after the right side
    "x := '1e400' == 1",  # a string beyond a double's range: strtod's ERANGE, an error
    "x := 1; x = '1e-310'",
]


def _outcome(code: str) -> tuple[str, dict[str, str]]:
    """One Script in BehaviorTree.CPP: "refused", "error" or its result and every entry."""
    xml = (
        '<root BTCPP_format="4"><BehaviorTree ID="Main">'
        f'<Script code="{_attr(code)}"/></BehaviorTree></root>'
    )
    try:
        tree = bt.BehaviorTreeFactory().create_tree_from_text(xml)
    except (RuntimeError, IndexError):
        return "refused", {}
    try:
        status = tree.tick_exactly_once()
    except RuntimeError:
        return "error", {}
    board = tree.root_blackboard()
    return str(status).rsplit(".", 1)[-1], {k: board.get_string(k) for k in board.get_keys()}


def _btcap_outcome(code: str) -> tuple[str, dict[str, str]]:
    xml = (
        '<root BTCPP_format="4"><BehaviorTree ID="Main">'
        f'<Script code="{_attr(code)}"/></BehaviorTree></root>'
    )
    try:
        tree = loads_tree(xml, "xml", default_registry(plugins=False))
    except TreeFileError:
        return "refused", {}
    with capture_logs(), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        state = tree.tick()
    if state is State.ERROR:
        return "error", {}
    values = {k: to_text(v) for k, v in tree.blackboard.outputs.items() if v is not None}
    return {State.SUCCEEDED: "SUCCESS", State.FAILED: "FAILURE"}[state], values


@pytest.mark.parametrize("code", FOUND)
def test_found_differences_stay_fixed(code: str) -> None:
    assert _btcap_outcome(code) == _outcome(code)


# -- trees with pre/post conditions, Precondition and Script leaves ---------------------


def _conditioned(root: El, rng: random.Random) -> El:
    """Counters on every kind of node: ``_onHalted`` on controls too, ``_while`` and
    ``_skipIf`` anywhere but on an IfThenElse/WhileDoElse condition (BehaviorTree.CPP
    throws there: documented), ``Precondition`` with each ``else`` around subtrees, and
    ``Script`` leaves that move the counters the conditions read."""
    root = script_oracle.with_conditions(root, rng, skips=True)
    conditions = {id(e.children[0]) for e in root.walk() if e.tag in ("IfThenElse", "WhileDoElse")}
    counter = [0]
    for el in root.walk():
        kids: list[El] = []
        for child in el.children:
            counter[0] += 1
            roll = rng.random()
            if "once" in (el.name, child.name) or id(child) in conditions:  # the init
                kids.append(child)
            elif roll < 0.12:
                guard = f"{rng.choice('sfph')} {rng.choice(('<', '>=', '!='))} {rng.randint(0, 3)}"
                other = rng.choice(("SUCCESS", "FAILURE", "RUNNING", "SKIPPED"))
                attrs = {"if": guard, "else": other}
                kids.append(El("Precondition", f"pc{counter[0]}", attrs, [child]))
            elif roll < 0.2 and el.tag in ("Sequence", "Fallback", "ReactiveSequence", "Parallel"):
                code = rng.choice(("p += 1", "s := s + 1", "f = f + 0; p += 1"))
                kids += [El("Script", f"sc{counter[0]}", {"code": code}), child]
            else:
                kids.append(child)
        el.children = kids
    # Documented: a control node or decorator that gave SKIPPED (its children skipped)
    # stays RUNNING in BehaviorTree.CPP, so it is halted later (its _onHalted runs) and
    # its pre-conditions are not checked on its next tick; none on such nodes here.
    for el in root.walk():
        if el.children and any(_skips(d) for d in el.walk()[1:]):
            for attr in ("_failureIf", "_successIf", "_skipIf", "_while"):
                el.attrs.pop(attr, None)
        elif el.children and rng.random() < 0.25:
            el.attrs["_onHalted"] = "h += 1"
    return root


def _skips(el: El) -> bool:
    """Whether ``el`` may give SKIPPED."""
    return (
        "_skipIf" in el.attrs
        or "_while" in el.attrs
        or (el.tag == "RunOnce" and "then_skip" not in el.attrs)
        or el.attrs.get("else") == "SKIPPED"
    )


@_settings(60)
@given(st.integers(0, 2**32), st.booleans())
def test_generated_trees_with_conditions_agree_with_behaviortree_cpp(seed: int, once: bool) -> None:
    rng = random.Random(seed)
    root = _conditioned(random_tree(rng, 3 + seed % 2), rng)
    with capture_logs(), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = script_oracle.compare_conditions(root, once=once)
    assert out.mismatch is None, out.mismatch
    documented = {"conditions_checked_when_idle", "refused by BehaviorTree.CPP", WAKES_FOREVER}
    assert out.error is None or out.error in documented | set(DIFFERENCES), out.error


def test_precondition_keeps_a_sequence_with_memory_in_place() -> None:
    """Found by the test above: a Precondition whose child finished only sets it back to
    IDLE in BehaviorTree.CPP, so a SequenceWithMemory below resumes at the child that
    failed; btcap reset the whole subtree."""
    from btcpp_oracle import BtcapRun, BtcppRun

    inner = '<SequenceWithMemory><Act name="a"/><Inverter><Act name="b"/></Inverter>'
    body = f'<Precondition if="true" else="FAILURE">{inner}</SequenceWithMemory></Precondition>'
    xml = f'<root BTCPP_format="4"><BehaviorTree ID="M">{body}</BehaviorTree></root>'
    scripts = {"a": "S", "b": "SF"}
    mine, theirs = BtcapRun(xml, scripts), BtcppRun(xml, scripts)
    got = [mine.tick() for _ in range(5)]
    assert got == [theirs.tick() for _ in range(5)]
    assert got[2] == ("S", ["tick b"])  # resumed at the Inverter


def test_a_skipped_control_node_is_halted_in_behaviortree_cpp_only() -> None:
    """Documented (docs/btcpp.md, Scripts): BehaviorTree.CPP's control node keeps the
    RUNNING status it set when it gave SKIPPED, so its parent halts it and its
    ``_onHalted`` runs; btcap's does not. If either side changes, so must the docs."""
    code = "h := 0"
    body = '<AsyncSequence _onHalted="h += 1"><AlwaysSuccess _skipIf="true"/></AsyncSequence>'
    xml = (
        '<root BTCPP_format="4"><BehaviorTree ID="Main"><Sequence>'
        f'<Script code="{code}"/>{body}</Sequence></BehaviorTree></root>'
    )
    theirs = bt.BehaviorTreeFactory().create_tree_from_text(xml)
    assert theirs.tick_exactly_once() == bt.NodeStatus.SUCCESS
    assert theirs.root_blackboard().get_string("h") == "1"
    mine = loads_tree(xml, "xml", default_registry(plugins=False))
    assert mine.tick() is State.SUCCEEDED
    assert mine.blackboard["h"] == 0
