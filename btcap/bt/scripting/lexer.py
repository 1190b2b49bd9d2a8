"""The tokens of BehaviorTree.CPP's scripting language, each with its column.

Written by hand from the grammar of BehaviorTree.CPP 4.8 (its ``any_types.hpp``): a
number must not run on into a letter, ``_`` or ``.`` (``1..2`` is an error there too),
``+3`` is a literal but ``-3`` is the negation of ``3`` (the parser's business), strings
are quoted with ``'`` or ``"`` and have no escapes. A new line is whitespace, as any
blank: statements are separated by ``;`` only. A literal must fit what BehaviorTree.CPP
stores it in: an integer an int64, a double a finite normal double (its ``std::stod``
refuses the rest), else the script is refused when it loads.
"""

from __future__ import annotations

import math
import re
from typing import NamedTuple

from btcap.errors import BtcapError

__all__ = ["ScriptSyntaxError", "Token", "tokenize"]


class ScriptSyntaxError(BtcapError, ValueError):
    """A script that does not parse; ``column`` is 1-based within the script."""

    def __init__(self, message: str, column: int, line: int = 1) -> None:
        super().__init__(message)
        self.message = message
        self.column = column
        self.line = line

    def __str__(self) -> str:
        where = f"line {self.line}, " if self.line > 1 else ""
        return f"{where}column {self.column}: {self.message}"


class Token(NamedTuple):
    kind: str  # "int", "real", "str", "name", "bool", "op", "end"
    text: str
    value: object
    pos: int  # 0-based offset in the script


_OPS = (
    ":=", "+=", "-=", "*=", "/=", "==", "!=", "<=", ">=", "&&", "||", "..",
    "<", ">", "=", "&", "|", "^", "~", "!", "+", "-", "*", "/", "?", ":", "(", ")", ";",
)  # fmt: skip
_NUMBER = re.compile(
    r"(?P<hex>0[xX][0-9a-fA-F]+)"
    r"|(?P<real>[+]?\d+(?:\.\d+(?:[eE][+-]?\d+)?|[eE][+-]?\d+))"
    r"|(?P<int>[+]?\d+)"
)
_NAME = re.compile(r"[A-Za-z_@]\w*")
_BLANK = " \t\r\f\v\n"
_INT64 = 2**63
_TINY = 2.2250738585072014e-308  # the smallest normal double


def _is_name_char(c: str) -> bool:
    return c.isalnum() or c == "_"


def _number(text: str, real: bool, pos: int) -> Token:
    """A number literal, refused where BehaviorTree.CPP 4.8's conversion throws."""
    if real:
        value = float(text)
        digits = text.lower().split("e")[0]
        if math.isinf(value) or (abs(value) < _TINY and digits.strip("+0.") != ""):
            raise ScriptSyntaxError("double literal out of range", pos + 1)
        return Token("real", text, value, pos)
    number = int(text, 16) if text[:2] in ("0x", "0X") else int(text)
    if number >= _INT64:
        raise ScriptSyntaxError("integer literal out of range (int64)", pos + 1)
    return Token("int", text, number, pos)


def tokenize(text: str) -> list[Token]:
    """The tokens of ``text``; a ScriptSyntaxError names the column of a bad character.

    ``+`` directly before a digit starts a literal only where an operand is expected
    (after an operator, ``(`` or at the start), as in BehaviorTree.CPP.
    """
    out: list[Token] = []
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if c in _BLANK:
            i += 1
            continue
        if c == "\\" and text[i + 1 : i + 2] == "\n":  # an escaped new line is a blank
            i += 2
            continue
        operand = not out or (out[-1].kind == "op" and out[-1].text != ")")
        if c.isdigit() or (c == "+" and operand and text[i + 1 : i + 2].isdigit()):
            m = _NUMBER.match(text, i)
            assert m is not None
            end = m.end()
            if end < n and (text[end] == "." or _is_name_char(text[end])):
                kind = "double" if m.lastgroup == "real" else "integer"
                raise ScriptSyntaxError(f"invalid suffix on {kind} literal", end + 1)
            out.append(_number(m.group(), m.lastgroup == "real", i))
            i = end
            continue
        if c in "'\"":
            end = text.find(c, i + 1)
            if end < 0:
                raise ScriptSyntaxError("missing closing quote", n + 1)
            body = text[i + 1 : end]
            if not body.isascii():
                raise ScriptSyntaxError("strings hold ASCII characters only", i + 1)
            out.append(Token("str", text[i : end + 1], body, i))
            i = end + 1
            continue
        m = _NAME.match(text, i)
        if m is not None:
            word = m.group()
            for lit, value in (("true", 1), ("false", 0)):
                if word.startswith(lit):
                    if len(word) > len(lit):  # BehaviorTree.CPP reads the keyword first
                        raise ScriptSyntaxError("expected ';'", i + len(lit) + 1)
                    out.append(Token("bool", word, value, i))
                    break
            else:
                out.append(Token("name", word, word, i))
            i = m.end()
            continue
        for op in _OPS:
            if text.startswith(op, i):
                out.append(Token("op", op, None, i))
                i += len(op)
                break
        else:
            raise ScriptSyntaxError(f"unexpected character {c!r}", i + 1)
    out.append(Token("end", "", None, n))
    return out
