"""The value rules of BehaviorTree.CPP 4.8's scripts, on Python values.

A script value is an ``int`` (BehaviorTree.CPP's int64; ``true``/``false`` and integer
literals), a ``float`` (double; every arithmetic, comparison and logic result) or a
``str``. Arithmetic on two numbers gives a float; ``+`` joins two strings and ``..``
joins strings and numbers (a float written as C++'s ``std::to_string`` writes it, six
decimals); bitwise operators need integral numbers, ``&&``/``||`` numbers that convert
to a bool (an integer must be 0 or 1) and evaluate both sides. Comparing a string with a
number reads the string as a number (``true``, ``false`` and enum names included).
An entry keeps the kind of its first value: a later assignment converts to it or fails
(:func:`convert`).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from typing import Any

from btcap.errors import BtcapError

__all__ = [
    "EXACT",
    "ScriptError",
    "convert",
    "exact",
    "integral",
    "kind",
    "to_bool",
    "to_number",
    "to_text",
]

_INT64 = 2**63
#: The largest integer a double holds exactly; BehaviorTree.CPP refuses to convert
#: larger ones (its arithmetic and comparisons work on doubles).
EXACT = 2**53 - 1
_TINY = 2.2250738585072014e-308  # the smallest normal double
_LEADING = re.compile(
    r"\s*(?P<sign>[+-]?)(?:0[xX](?P<hex>[0-9a-fA-F]+\.?[0-9a-fA-F]*|\.[0-9a-fA-F]+)"
    r"(?P<exp>[pP][+-]?\d+)?"
    r"|(?P<dec>(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|inf(?:inity)?|nan))",
    re.IGNORECASE,
)


class ScriptError(BtcapError, RuntimeError):
    """A script failed while running (BehaviorTree.CPP throws at the same points)."""


def kind(value: object) -> str:
    if isinstance(value, str):
        return "string"
    if isinstance(value, float):
        return "double"
    if isinstance(value, int):
        return "integer"
    return "empty value" if repr(value) == "empty" else type(value).__name__


def exact(value: Any) -> Any:
    """``value``, unless it is an integer too large to become a double exactly."""
    if type(value) is int and not -EXACT <= value <= EXACT:
        raise ScriptError(f"loss of precision converting the integer {value} to a double")
    return value


def to_text(value: object) -> str:
    """A value as ``..`` writes it (C++ ``std::to_string`` for numbers)."""
    if isinstance(value, str):
        return value
    if isinstance(value, float):
        if math.isnan(value):
            return "nan" if math.copysign(1.0, value) > 0 else "-nan"
        return f"{value:f}"
    return str(value)


def to_number(text: str, enums: Mapping[str, int], *, words: bool = True) -> float:
    """A string compared with (or assigned to) a number: true/false, an enum, a number
    (``words=False``: a number only, as the condition of ``c ? a : b`` reads it)."""
    if words:
        if text == "true":
            return 1.0
        if text == "false":
            return 0.0
        if text in enums:
            return float(enums[text])
    m = _LEADING.match(text)  # C's strtod: the number the string starts with
    if m is None:
        raise ScriptError(f"the string {text!r} is not a number")
    # strtod's ERANGE, which BehaviorTree.CPP's conversion refuses: a number too large,
    # or a decimal one too small for a normal double (an exact hexadecimal one is kept)
    too = ScriptError(f"the string {text!r} holds a number out of a double's range")
    if m.group("hex"):  # C99's hexadecimal floats too: '0x1.8p1' is 3
        try:
            value = float.fromhex(m.group("hex") + (m.group("exp") or "p0"))
        except OverflowError:
            raise too from None
    else:
        digits = m.group("dec")
        value = float(digits)
        if digits[0].isalpha():  # inf, nan: as written
            return float(m.group("sign") + digits)
        if math.isinf(value) or (value < _TINY and digits.lower().split("e")[0].strip("0.")):
            raise too
    return -value if m.group("sign") == "-" else value


def to_bool(value: object, what: str) -> bool:
    """BehaviorTree.CPP's cast to bool: a double not negative, an integer only 0 or 1."""
    if isinstance(value, float):
        if value < 0:
            raise ScriptError(f"{what}: the negative number {to_text(value)} is not a bool")
        return value != 0.0
    if isinstance(value, int):
        if value in (0, 1):
            return bool(value)
        raise ScriptError(f"{what}: the integer {value} is not a bool (only 0 and 1 are)")
    raise ScriptError(f"{what}: a {kind(value)} is not a bool")


def integral(value: float, what: str) -> int:
    """A float that holds an int64 exactly, as that int (else an error, as in C++)."""
    if not math.isfinite(value) or value != math.floor(value) or not -_INT64 <= value < _INT64:
        raise ScriptError(f"{what}: {to_text(value)} is not an integer")
    return int(value)


def convert(value: Any, old: Any, key: str, declared: Any, enums: Mapping[str, int]) -> Any:
    """``value`` as entry ``key`` holds it, given its ``old`` value (None: none yet) and
    the type a node port declares for it (``Any``: none)."""
    if declared is not Any and declared in (int, float, str, bool):
        return _to_type(value, declared, key, enums)
    if old is None:
        return value
    if isinstance(old, str):
        if isinstance(value, str):
            return value
        raise ScriptError(f"entry {key!r} holds a string; a {kind(value)} cannot be assigned to it")
    if isinstance(value, str):  # BehaviorTree.CPP reads it as a number, kept as a double
        return to_number(value, enums)
    if isinstance(old, float):
        return float(exact(value))
    if isinstance(old, int) and isinstance(value, float):
        return integral(value, f"entry {key!r} holds an integer")
    if isinstance(value, int) and isinstance(old, int):
        return value
    return _to_type(value, type(old), key, enums)


def _to_type(value: Any, tp: Any, key: str, enums: Mapping[str, int]) -> Any:
    what = f"entry {key!r} is {tp.__name__}"
    if isinstance(value, tp) and not (tp is int and isinstance(value, bool)):
        return value
    if tp is str:
        raise ScriptError(f"{what}; a {kind(value)} cannot be assigned to it")
    if isinstance(value, str):
        value = to_number(value, enums)
    if not isinstance(value, (int, float)):
        raise ScriptError(f"{what}; a {kind(value)} cannot be assigned to it")
    if tp is bool:
        return to_bool(value, what)
    if tp is int:
        return integral(value, what) if isinstance(value, float) else int(value)
    return float(exact(value))
