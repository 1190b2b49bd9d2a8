"""BehaviorTree.CPP's scripting grammar, parsed by precedence climbing into a small AST.

The precedence of BehaviorTree.CPP 4.8, lowest first: assignment (``:=`` creates an
entry, ``=`` assigns an existing one, ``+= -= *= /=``; not chained), the conditional
``c ? a : b`` (not chained), ``&&`` and ``||`` (one level, left to right), comparisons
(chained: ``a < b < c``), then one of three families that may not be mixed without
parentheses (within one whole expression, comparisons and ``&&`` included):
arithmetic (unary ``-``, then ``* /``, then ``+ -``), bitwise (``~`` and
``!``, then ``&``, then ``| ^``) and string concatenation ``..``. BehaviorTree.CPP 4.8
groups arithmetic to the right: ``1 - 2 - 3`` is ``1 - (2 - 3)`` and ``8 / 2 * 2`` is
``8 / (2 * 2)``; the others to the left (checked against it). A prefix operator
applies to an atom (a literal, an entry name, ``true``/``false`` or a parenthesised
expression), perhaps after more prefixes of its family: ``--x`` and ``~!x`` are read,
``-~x`` is refused. Statements are separated by ``;``.

A hand parser: the language is tiny and its rules (the families, chaining) are
BehaviorTree.CPP's own, which no general parser library states more simply; this one
reports the exact column of each error.
"""

from __future__ import annotations

import dataclasses
import functools

from btcap.bt.scripting.lexer import ScriptSyntaxError, Token, tokenize

__all__ = ["Expr", "Script", "parse"]

#: An expression: ("lit", pos, value) | ("name", pos, key) | ("unary", pos, op, e)
#: | ("bin", pos, op, l, r) | ("cmp", pos, ops, operands) | ("if", pos, c, a, b)
#: | ("assign", pos, op, key, value). ``pos`` is the 0-based offset in the script.
Expr = tuple[object, ...]

_ASSIGN = (":=", "=", "+=", "-=", "*=", "/=")
_COMPARE = ("==", "!=", "<", ">", "<=", ">=")
_FAMILY = {
    "+": "math", "-": "math", "*": "math", "/": "math",
    "&": "bit", "|": "bit", "^": "bit", "..": "concat",
}  # fmt: skip
_LEVEL = {"+": 1, "-": 1, "*": 2, "/": 2, "|": 1, "^": 1, "&": 2, "..": 1}


@dataclasses.dataclass(frozen=True)
class Script:
    """A parsed script: its statements and the entries it reads and writes."""

    text: str
    statements: tuple[Expr, ...]
    #: Entries read, assigned (any operator) and created (``:=``), by first use.
    reads: tuple[str, ...]
    writes: tuple[str, ...]
    creates: tuple[str, ...]


class _Parser:
    def __init__(self, text: str) -> None:
        self.toks = tokenize(text)
        self.i = 0
        self.reads: dict[str, int] = {}  # entry -> where first read
        self.writes: dict[str, None] = {}
        self.creates: dict[str, None] = {}
        self.seen: list[str] = []  # operator families used in the current expression

    def peek(self) -> Token:
        return self.toks[self.i]

    def take(self) -> Token:
        tok = self.peek()
        self.i += 1
        return tok

    def is_op(self, *ops: str) -> bool:
        tok = self.peek()
        return tok.kind == "op" and tok.text in ops

    def fail(self, msg: str, tok: Token | None = None) -> ScriptSyntaxError:
        return ScriptSyntaxError(msg, (tok or self.peek()).pos + 1)

    def statements(self) -> tuple[Expr, ...]:
        if self.peek().kind == "end":
            raise self.fail("empty script")
        out = [self.expression()]
        while self.is_op(";"):
            self.take()
            if self.peek().kind == "end":
                raise self.fail("unexpected trailing separator", self.toks[self.i - 1])
            out.append(self.expression())
        if self.peek().kind != "end":
            raise self.fail("expected ';'")
        return tuple(out)

    def expression(self) -> Expr:
        """An expression; operator families may not mix within one (parentheses and
        the middle of ``c ? a : b`` start a new one), as in BehaviorTree.CPP 4.8."""
        outer, self.seen = self.seen, []
        try:
            return self._assignment()
        finally:
            self.seen = outer

    def _assignment(self) -> Expr:
        lhs = self.conditional()
        if not self.is_op(*_ASSIGN):
            return lhs
        tok = self.take()
        if lhs[0] != "name":
            raise self.fail(f"the left of {tok.text!r} must be a blackboard entry", tok)
        key = str(lhs[2])
        if tok.text in (":=", "=") and self.reads.get(key) == lhs[1]:
            del self.reads[key]  # only assigned here, not read
        self.writes[key] = None
        if tok.text == ":=":
            self.creates[key] = None
        rhs = self.conditional()
        if self.is_op(*_ASSIGN):
            raise self.fail("operator cannot be chained")
        return ("assign", tok.pos, tok.text, key, rhs)

    def conditional(self) -> Expr:
        cond = self.logical()
        if not self.is_op("?"):
            return cond
        tok = self.take()
        then = self.expression()
        if not self.is_op(":"):
            raise self.fail("expected ':'")
        self.take()
        other = self.logical()
        if self.is_op("?"):
            raise self.fail("operator cannot be chained")
        return ("if", tok.pos, cond, then, other)

    def logical(self) -> Expr:
        lhs = self.comparison()
        while self.is_op("&&", "||"):
            tok = self.take()
            lhs = ("bin", tok.pos, tok.text, lhs, self.comparison())
        return lhs

    def comparison(self) -> Expr:
        first = self.family()
        if not self.is_op(*_COMPARE):
            return first
        ops, operands, pos = [], [first], self.peek().pos
        while self.is_op(*_COMPARE):
            ops.append(self.take().text)
            operands.append(self.family())
        return ("cmp", pos, tuple(ops), tuple(operands))

    def family(self) -> Expr:
        """Operators of one family (arithmetic, bitwise or ``..``), by precedence."""
        return self.binary(1, self.seen)

    def binary(self, level: int, seen: list[str]) -> Expr:
        lhs = self.prefix(seen)
        while True:
            tok = self.peek()
            op = tok.text if tok.kind == "op" else ""
            fam = _FAMILY.get(op)
            if fam is None or _LEVEL[op] < level:
                return lhs
            if seen and seen[0] != fam:
                raise self.fail("operator cannot be mixed with previous operators")
            seen.append(fam)
            self.take()
            # BehaviorTree.CPP 4.8 groups arithmetic to the right: 1 - 2 - 3 is 1 - (2 - 3)
            right = _LEVEL[op] + (fam != "math")
            lhs = ("bin", tok.pos, op, lhs, self.binary(right, seen))

    def prefix(self, seen: list[str]) -> Expr:
        if self.is_op("-", "~", "!"):
            tok = self.take()
            fam = "math" if tok.text == "-" else "bit"
            if seen and seen[0] != fam:
                raise self.fail("operator cannot be mixed with previous operators", tok)
            seen.append(fam)
            # More prefixes of the same family may follow (BehaviorTree.CPP 4.8 reads
            # ``--x`` and ``~!x``; ``-~x`` mixes two families and is refused there too).
            same = ("-",) if fam == "math" else ("~", "!")
            inner = self.prefix(seen) if self.is_op(*same) else self.atom()
            return ("unary", tok.pos, tok.text, inner)
        return self.atom()

    def atom(self) -> Expr:
        tok = self.take()
        if tok.kind in ("int", "real", "str", "bool"):
            return ("lit", tok.pos, tok.value)
        if tok.kind == "name":
            key = tok.text
            self.reads.setdefault(key, tok.pos)
            return ("name", tok.pos, key)
        if tok.kind == "op" and tok.text == "(":
            inner = self.expression()
            if not self.is_op(")"):
                raise self.fail("expected ')'")
            self.take()
            return inner
        raise self.fail("expected operand", tok)


@functools.lru_cache(maxsize=1024)
def parse(text: str) -> Script:
    """The parsed script (cached: a script is parsed once however often it is loaded)."""
    p = _Parser(text)
    stmts = p.statements()
    return Script(text, stmts, tuple(p.reads), tuple(p.writes), tuple(p.creates))
