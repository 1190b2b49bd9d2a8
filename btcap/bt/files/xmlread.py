"""A small, safe XML reader that keeps the line of every element, for error messages.

Built on the standard library's expat parser. Like tinyxml2, which BehaviorTree.CPP
reads its files with, it takes a raw ``&`` or ``<`` in an attribute value as itself
(scripts write ``a > 1 && b``). Tree files come from other people, so
document type declarations are refused outright (no entity expansion, no external
entities: what defusedxml forbids), and the text is parsed without fetching anything.
"""

from __future__ import annotations

import dataclasses
import re
from typing import Any
from xml.parsers import expat

from btcap.bt.files.schema import TreeFileError

__all__ = ["MAX_DEPTH", "XmlElement", "read_xml"]

#: Elements nested deeper than this are refused (reading and building trees recurse).
MAX_DEPTH = 200


@dataclasses.dataclass
class XmlElement:
    """One element: its tag, attributes in document order, line, children and text.

    ``where`` names the file it is in (a tree may come from several, by ``<include>``).
    """

    tag: str
    attrs: dict[str, str]
    line: int
    children: list[XmlElement] = dataclasses.field(default_factory=list)
    text: str = ""
    where: str = ""


#: Comments, CDATA, processing instructions (left alone) and start tags (attributes fixed).
_MARKUP = re.compile(
    r"<!--.*?-->|<!\[CDATA\[.*?\]\]>|<\?.*?\?>"
    r"|<[A-Za-z_:][\w:.-]*(?:\s+[^\s=/>]+\s*=\s*(?:\"[^\"]*\"|'[^']*'))*\s*/?>",
    re.DOTALL,
)
_QUOTED = re.compile(r"\"[^\"]*\"|'[^']*'")
_RAW = re.compile(r"&(?!(?:amp|lt|gt|quot|apos|#[0-9]+|#x[0-9a-fA-F]+);)|<")


def _escape_raw(m: re.Match[str]) -> str:
    return "&amp;" if m.group() == "&" else "&lt;"


def _lenient(text: str) -> str:
    """``text`` with a raw ``&`` or ``<`` inside attribute values escaped.

    BehaviorTree.CPP reads its files with tinyxml2, which keeps such characters as they
    are (its tutorials write ``code="a > 1 && b"``); XML parsers refuse them. Only
    attribute values change, and no line moves.
    """

    def tag(m: re.Match[str]) -> str:
        markup = m.group()
        if not markup.startswith("<") or markup[1] in "!?":
            return markup
        return _QUOTED.sub(
            lambda q: q.group()[0] + _RAW.sub(_escape_raw, q.group()[1:-1]) + q.group()[0], markup
        )

    return _MARKUP.sub(tag, text)


class _Refused(Exception):
    """Raised from an expat handler to stop parsing a document btcap will not read."""


def read_xml(data: bytes | str, where: str) -> XmlElement:
    """The root element of ``data``; malformed or unsafe XML is a TreeFileError with a line."""
    parser = expat.ParserCreate()
    stack: list[XmlElement] = []
    roots: list[XmlElement] = []

    def start(tag: str, attrs: dict[str, str]) -> None:
        if len(stack) >= MAX_DEPTH:
            raise _Refused(
                f"line {parser.CurrentLineNumber}: <{tag}> is nested {MAX_DEPTH + 1} "
                f"elements deep; btcap reads at most {MAX_DEPTH}"
            )
        el = XmlElement(tag, dict(attrs), parser.CurrentLineNumber, where=where)
        (stack[-1].children if stack else roots).append(el)
        stack.append(el)

    def end(tag: str) -> None:
        stack.pop()

    def text(data: str) -> None:
        if stack:
            stack[-1].text += data

    def refuse(*args: Any) -> None:
        raise _Refused(
            f"line {parser.CurrentLineNumber}: a DOCTYPE or entity declaration; btcap "
            f"does not read them (they can expand without bound or reach outside the file)"
        )

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = text
    parser.StartDoctypeDeclHandler = refuse
    parser.EntityDeclHandler = refuse
    if isinstance(data, bytes) and ("&" in (raw := data.decode("latin-1")) or "<" in raw):
        data = _lenient(raw).encode("latin-1")  # latin-1 maps every byte to itself
    elif isinstance(data, str):
        data = _lenient(data)
    try:
        parser.Parse(data, True)
    except _Refused as exc:
        raise TreeFileError([f"{where}: {exc}"]) from None
    except expat.ExpatError as exc:
        raise TreeFileError(
            [
                f"{where}: line {exc.lineno}: malformed XML: "
                f"{expat.errors.messages[exc.code]} (column {exc.offset + 1})"
            ]
        ) from None
    return roots[0]
