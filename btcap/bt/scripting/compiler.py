"""A parsed script made into Python closures over the blackboard entries it uses.

Compiled once when the tree is built: entry names are resolved to their blackboard then
(remaps of subtrees included), enum names to their values, literals to constants, so a
tick runs only the closures. Semantics: :mod:`btcap.bt.scripting.values`.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Callable, Mapping
from typing import Any, Protocol

from btcap.bt.scripting.parser import Expr, Script
from btcap.bt.scripting.values import (
    EXACT,
    ScriptError,
    convert,
    exact,
    integral,
    kind,
    to_bool,
    to_number,
    to_text,
)

__all__ = ["Cell", "Compiled", "compile_script"]

Compiled = Callable[[], Any]


class _Empty:
    """The value of ``..`` on two numbers: none (BehaviorTree.CPP's empty Any)."""

    __slots__ = ()

    def __repr__(self) -> str:
        return "empty"


EMPTY = _Empty()


class Cell(Protocol):
    """Where a script finds one entry: its value dict, name there and declared type."""

    values: dict[str, Any]
    name: str
    type: Any

    def arrived(self) -> None:
        """Called before the entry's first value is stored."""


def _read(cell: Cell, key: str) -> Compiled:
    values, name = cell.values, cell.name

    def read() -> Any:
        v = values.get(name)
        t = type(v)
        if t is float or t is int or t is str:
            return v
        return _odd_value(v, key)

    return read


def _odd_value(v: Any, key: str) -> Any:
    """An entry value that is not a script value: none yet, a bool, or another type."""
    if v is None:
        raise ScriptError(f"entry {key!r} has no value yet")
    if v is True or v is False:
        return int(v)
    return v


_ARITH: dict[str, Callable[[float, float], float]] = {
    "+": operator.add,
    "-": operator.sub,
    "*": operator.mul,
    "/": lambda a, b: a / b if b else _divide(a, b),
}


def _divide(a: float, b: float) -> float:
    """IEEE division by zero, as C++ doubles do on x86-64 (0/0 is its default NaN, whose
    sign bit is set: BehaviorTree.CPP writes it ``-nan``)."""
    if a != a:
        return a
    if a == 0:
        return -math.nan
    return math.inf if (a > 0) == (math.copysign(1.0, b) > 0) else -math.inf


def _number(v: Any) -> bool:
    return type(v) is int or type(v) is float


def _arith_error(op: str, a: Any, b: Any) -> Any:
    if _number(a) and _number(b):
        return float(_ARITH[op](exact(a), exact(b)))  # raises for a large integer
    if op == "+" and type(a) is str and type(b) is str:
        return a + b
    raise ScriptError(f"operator {op!r}: not permitted on a {kind(a)} and a {kind(b)}")


def _binary(
    op: str, lhs: Compiled, rhs: Compiled, const: Any = None, entry: Cell | None = None
) -> Compiled:
    """``const``: the right side, if it is a number literal; ``entry``: the left side, if it
    is an entry (read inline: the usual ``n + 1`` costs one call)."""
    if op in _ARITH:
        f = _ARITH[op]
        if type(const) is int and not -EXACT <= const <= EXACT:
            const = None  # no double holds it exactly: checked, as the left side is
        if const is not None and entry is not None:
            k, values, name, key = const, entry.values, entry.name, entry.name

            def arith_entry_k() -> Any:
                a: Any = values.get(name)
                ta = type(a)
                if ta is float or (ta is int and -EXACT <= a <= EXACT):
                    return float(f(a, k))
                return _arith_error(op, _odd_value(a, key), k)

            return arith_entry_k
        if const is not None:
            k = const

            def arith_k() -> Any:
                a = lhs()
                ta = type(a)
                if ta is float or (ta is int and -EXACT <= a <= EXACT):
                    return float(f(a, k))
                return _arith_error(op, a, k)

            return arith_k

        def arith() -> Any:
            a = lhs()
            b = rhs()
            ta, tb = type(a), type(b)
            if (ta is float or (ta is int and -EXACT <= a <= EXACT)) and (
                tb is float or (tb is int and -EXACT <= b <= EXACT)
            ):
                return float(f(a, b))
            return _arith_error(op, a, b)

        return arith
    if op == "..":

        def concat() -> Any:
            a, b = lhs(), rhs()
            if (
                (type(a) is str or type(b) is str)
                and (_number(a) or type(a) is str)
                and (_number(b) or type(b) is str)
            ):
                return to_text(a) + to_text(b)
            if _number(a) and _number(b):
                return EMPTY  # BehaviorTree.CPP gives no value here, an error only if used
            raise ScriptError(f"operator '..': not permitted on a {kind(a)} and a {kind(b)}")

        return concat
    if op in ("&&", "||"):
        both = op == "&&"

        def logic() -> Any:
            a, b = lhs(), rhs()  # both sides run, as in BehaviorTree.CPP
            if not (_number(a) and _number(b)):
                raise ScriptError(f"operator {op!r}: not permitted on a {kind(a)} and a {kind(b)}")
            x, y = to_bool(a, f"operator {op!r}"), to_bool(b, f"operator {op!r}")
            return float((x and y) if both else (x or y))

        return logic
    bit = {"&": operator.and_, "|": operator.or_, "^": operator.xor}[op]

    def bitwise() -> Any:
        a, b = lhs(), rhs()
        if not (_number(a) and _number(b)):
            raise ScriptError(f"operator {op!r}: not permitted on a {kind(a)} and a {kind(b)}")
        what = f"operator {op!r} needs integers"
        # an integer goes through a double first, as in BehaviorTree.CPP: 2**53 is refused
        x = integral(a, what) if type(a) is float else exact(a)
        y = integral(b, what) if type(b) is float else exact(b)
        return float(bit(x, y))

    return bitwise


def _same(op: str, a: Any, b: Any) -> bool:
    """One comparison; doubles are equal within float epsilon, as in BehaviorTree.CPP."""
    if op in ("==", "!="):
        eq = abs(a - b) <= 1.1920928955078125e-07 if type(a) is float else a == b
        return eq if op == "==" else not eq
    return _ORDER[op](a, b)


#: BehaviorTree.CPP tests the opposite and negates it (``a < b`` is ``not a >= b``), so
#: a comparison with NaN is true where IEEE's would be false.
_ORDER: dict[str, Callable[[Any, Any], bool]] = {
    "<": lambda a, b: not a >= b,
    ">": lambda a, b: not a <= b,
    "<=": lambda a, b: not a > b,
    ">=": lambda a, b: not a < b,
}


_IEEE: dict[str, Callable[[Any, Any], bool]] = {
    "<": operator.lt,
    ">": operator.gt,
    "<=": operator.le,
    ">=": operator.ge,
}


def _compare(
    ops: tuple[str, ...],
    operands: list[Compiled],
    enums: Mapping[str, int],
    entries: list[Cell | None] | None = None,
) -> Compiled:
    """``entries``: the cell of each operand that is an entry (read inline when both are)."""

    def step(op: str, a: Any, b: Any) -> bool:
        exact(a), exact(b)  # a large integer is no double
        if _number(a) and _number(b):
            return _same(op, float(a), float(b))
        if type(a) is str and type(b) is str:
            return _same(op, a, b)
        if type(a) is str and _number(b):
            return _same(op, to_number(a, enums), float(b))
        if _number(a) and type(b) is str:
            return _same(op, float(a), to_number(b, enums))
        raise ScriptError(f"cannot compare a {kind(a)} with a {kind(b)}")

    if len(ops) == 1 and ops[0] in _ORDER:  # the usual case, numbers inline
        op, left, right = ops[0], operands[0], operands[1]
        fast = _IEEE[op]
        ea, eb = entries if entries and len(entries) == 2 else (None, None)
        if ea is not None and eb is not None:
            va, na, vb, nb = ea.values, ea.name, eb.values, eb.name

            def compare_entries() -> Any:
                a: Any = va.get(na)
                b: Any = vb.get(nb)
                ta, tb = type(a), type(b)
                if (ta is float or (ta is int and -EXACT <= a <= EXACT)) and (
                    tb is float or (tb is int and -EXACT <= b <= EXACT)
                ):
                    fa, fb = float(a), float(b)  # NaN: true, as _ORDER says
                    return 1.0 if fast(fa, fb) or fa != fa or fb != fb else 0.0
                return 1.0 if step(op, left(), right()) else 0.0

            return compare_entries

        def compare1() -> Any:
            a = left()
            b = right()
            ta, tb = type(a), type(b)
            if (ta is float or (ta is int and -EXACT <= a <= EXACT)) and (
                tb is float or (tb is int and -EXACT <= b <= EXACT)
            ):
                fa, fb = float(a), float(b)  # NaN: true, as _ORDER says
                return 1.0 if fast(fa, fb) or fa != fa or fb != fb else 0.0
            return 1.0 if step(op, a, b) else 0.0

        return compare1

    def compare() -> Any:
        a = operands[0]()
        for op, right in zip(ops, operands[1:], strict=True):
            b = right()
            if not step(op, a, b):
                return 0.0
            a = b
        return 1.0

    return compare


def _unary(op: str, arg: Compiled) -> Compiled:
    def unary() -> Any:
        v = exact(arg())
        if not _number(v):
            raise ScriptError(f"operator {op!r}: not permitted on a {kind(v)}")
        if op == "-":
            return -float(v)
        if op == "!":
            return 0.0 if v else 1.0
        if not -(2**63) <= v < 2**63:
            raise ScriptError("number out of range for a bitwise operation")
        return float(~int(v))

    return unary


def _assign(
    op: str, key: str, cell: Cell, rhs: Compiled, enums: Mapping[str, int], literal: Expr
) -> Compiled:
    values, name, declared = cell.values, cell.name, cell.type
    fixed = literal[0] == "lit"  # a literal right side is not called for
    k: Any = literal[2] if fixed else None
    arith = _ARITH.get(op[0])
    untyped = declared is Any
    plain = op in (":=", "=")

    def store(new: Any) -> Any:
        if name not in values:
            cell.arrived()
        values[name] = new
        return new

    create = op == ":="

    def assign() -> Any:
        old: Any
        if fixed:
            old = values.get(name)
            if old is None and not create and untyped:
                raise ScriptError(f"entry {key!r} does not exist yet; create it with ':='")
            value = k
        else:
            if not create and untyped and values.get(name) is None:
                raise ScriptError(f"entry {key!r} does not exist yet; create it with ':='")
            value = rhs()  # first: it may assign the entry (BehaviorTree.CPP reads it after)
            old = values.get(name)
        t = type(value)
        if value is EMPTY:
            raise ScriptError(f"the value assigned to {key!r} is empty ('..' of two numbers)")
        if plain:
            if (untyped and type(old) is t) or declared is t:  # the same kind: kept as is
                values[name] = value
                return value
            return store(convert(value, old, key, declared, enums))
        to = type(old)
        if (to is float or (to is int and -EXACT <= old <= EXACT)) and (
            t is float or (t is int and -EXACT <= value <= EXACT)
        ):
            assert arith is not None
            new = float(arith(old, value))
            if to is float and (untyped or declared is float):
                values[name] = new
                return new
            return store(convert(new, old, key, declared, enums))
        if _number(old) and _number(value):  # a large integer: no double
            return store(convert(float(arith(exact(old), exact(value))), old, key, declared, enums))  # type: ignore[misc]
        if old is None:
            raise ScriptError(f"entry {key!r} has no value for {op!r}")
        if t is float or t is int:
            raise ScriptError(f"{op!r} needs a number in entry {key!r}")
        if op == "+=" and to is str and t is str:
            return store(old + value)
        raise ScriptError(f"{op!r} is not permitted on a {kind(old)} and a {kind(value)}")

    return assign


def compile_expr(e: Expr, cells: Mapping[str, Cell], enums: Mapping[str, int]) -> Compiled:
    tag = e[0]
    if tag == "lit":
        value = e[2]
        return lambda: value
    if tag == "name":
        key = str(e[2])
        if key in enums:
            number = float(enums[key])
            return lambda: number
        return _read(cells[key], key)
    if tag == "unary":
        return _unary(str(e[2]), compile_expr(e[3], cells, enums))  # type: ignore[arg-type]
    if tag == "bin":
        sides = [compile_expr(x, cells, enums) for x in e[3:5]]  # type: ignore[arg-type]
        right = e[4]
        const = right[2] if right[0] == "lit" and type(right[2]) in (int, float) else None  # type: ignore[index]
        left = e[3]
        entry = cells.get(str(left[2])) if left[0] == "name" and left[2] not in enums else None  # type: ignore[index]
        return _binary(str(e[2]), sides[0], sides[1], const, entry)
    if tag == "cmp":
        operands = [compile_expr(x, cells, enums) for x in e[3]]  # type: ignore[attr-defined]
        entries = [
            cells[str(x[2])] if x[0] == "name" and x[2] not in enums else None
            for x in e[3]  # type: ignore[attr-defined]
        ]
        return _compare(e[2], operands, enums, entries)  # type: ignore[arg-type]
    if tag == "if":
        cond, then, other = (compile_expr(x, cells, enums) for x in e[2:5])  # type: ignore[arg-type]

        def branch() -> Any:
            c = cond()
            yes = _truthy(c)
            return then() if yes else other()

        return branch
    key = str(e[3])
    value = e[4]
    rhs = compile_expr(value, cells, enums)  # type: ignore[arg-type]
    return _assign(str(e[2]), key, cells[key], rhs, enums, value)  # type: ignore[arg-type]


def _truthy(c: Any) -> bool:
    """The condition of ``c ? a : b``: a string must hold a number (even ``'true'``
    fails), as in BehaviorTree.CPP 4.8."""
    if type(c) is str:
        return to_number(c, {}, words=False) != 0.0
    return float(exact(c)) != 0.0


def compile_script(script: Script, cells: Mapping[str, Cell], enums: Mapping[str, int]) -> Compiled:
    """The script as one closure returning its last statement's value."""
    parts = [compile_expr(s, cells, enums) for s in script.statements]
    if len(parts) == 1:
        return parts[0]
    if len(parts) == 2:
        p0, p1 = parts

        def run2() -> Any:
            p0()
            return p1()

        return run2
    if len(parts) == 3:
        q0, q1, q2 = parts

        def run3() -> Any:
            q0()
            q1()
            return q2()

        return run3
    *first, last = parts

    def run() -> Any:
        for f in first:
            f()
        return last()

    return run
