"""The reference of a file format, generated from the msgspec types that read it: a JSON
Schema for editors and a Markdown section listing every field with its path, type,
default and meaning, so neither can fall behind the code.

Generic over msgspec Structs: a field's meaning is its ``msgspec.Meta(description=...)``,
its bounds are the Meta's constraints, a section's text is its Struct's docstring. A
field marked ``Meta(extra={"internal": True})`` is set by the program, not the file, and
left out. A field without a description is an error: the reference would have a hole.
"""

from __future__ import annotations

import inspect
import json
import re
from dataclasses import dataclass
from pathlib import PurePath
from typing import Any

import msgspec
import msgspec.inspect as mi

__all__ = ["FileFormat", "json_schema", "markdown", "schema_text"]

_DIALECT = "https://json-schema.org/draft/2020-12/schema"
_ROLE = re.compile(r":[\w:]+:`~?([^`]+)`")  # :class:`~a.b.C` (Sphinx) as `C`


@dataclass(frozen=True)
class FileFormat:
    """A kind of file and the type it decodes into."""

    #: Short name: ``btcap schema NAME``, the schema file ``NAME.schema.json``.
    name: str
    #: The section's heading: "Scenario files".
    title: str
    #: What one file is called in the headings of its parts: "Scenario", "Agent file".
    label: str
    #: The msgspec Struct a whole file decodes into.
    type: type[Any]
    #: Markdown: what reads these files and how they are checked.
    about: str
    #: A complete example file (YAML).
    example: str = ""


# -- JSON Schema ----------------------------------------------------------------------------


def json_schema(fmt: FileFormat) -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of ``fmt``'s files, internal fields left out."""
    schema = msgspec.json.schema(fmt.type, schema_hook=_schema_hook)
    defs: dict[str, Any] = schema.get("$defs", {})
    for struct, _path in _structs(fmt.type):
        definition = defs.get(struct.cls.__name__)
        if definition is None:
            continue
        for f in struct.fields:
            if _internal(f):
                definition.get("properties", {}).pop(f.encode_name, None)
                if f.encode_name in definition.get("required", ()):
                    definition["required"].remove(f.encode_name)
        if "description" in definition:
            definition["description"] = _unwrapped(_plain(definition["description"]))
    return {
        "$schema": _DIALECT,
        "title": f"btcap {fmt.label.lower()}",  # "btcap scenario"
        "description": _unwrapped(_plain(fmt.about)),
        **schema,
    }


def schema_text(fmt: FileFormat) -> str:
    """:func:`json_schema` as the text of a ``.schema.json`` file."""
    return json.dumps(json_schema(fmt), indent=2, ensure_ascii=False) + "\n"


def _unwrapped(text: str) -> str:
    """Paragraphs on one line each: an editor wraps a description itself."""
    return "\n\n".join(" ".join(p.split()) for p in text.strip().split("\n\n"))


def _schema_hook(kind: type[Any]) -> dict[str, Any]:
    if isinstance(kind, type) and issubclass(kind, PurePath):
        return {"type": "string"}
    raise NotImplementedError


# -- Markdown -------------------------------------------------------------------------------


def markdown(fmt: FileFormat, *, level: int = 2) -> str:
    """A section on ``fmt``: its text, its example, and a table of fields per Struct."""
    head = "#" * level
    parts = [f"{head} {fmt.title}\n", fmt.about.strip() + "\n"]
    if fmt.example:
        parts.append(f"```yaml\n{fmt.example.strip()}\n```\n")
    sections = _structs(fmt.type)
    paths = {s.cls: path for s, path in sections}
    for struct, path in sections:
        parts.append(f"{head}# {fmt.label} {f'`{path}`' if path else 'top level'}\n")
        doc = _plain(inspect.cleandoc(struct.cls.__doc__ or ""))
        if doc and path:
            parts.append(doc + "\n")
        elsewhere = [p for s, p in _structs(fmt.type, unique=False) if s.cls is struct.cls]
        if len(elsewhere) > 1:
            parts.append("The same fields at " + ", ".join(f"`{p}`" for p in elsewhere) + ".\n")
        rows = ["| field | type | default | meaning |", "|---|---|---|---|"]
        for f in struct.fields:
            if _internal(f):
                continue
            where = f"{path}.{f.encode_name}" if path else f.encode_name
            meaning = _description(f)
            if not meaning:
                raise ValueError(f"{fmt.name}: {where}: no description (msgspec.Meta)")
            cells = (f"`{where}`", _type(f.type, fmt.label, paths), _default(f), _plain(meaning))
            rows.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
        parts.append("\n".join(rows) + "\n")
    return "\n".join(parts)


def _structs(root: type[Any], *, unique: bool = True) -> list[tuple[mi.StructType, str]]:
    """Every Struct in ``root``'s files with the path it is first (or, not ``unique``,
    each time) found at, depth first in field order; ``""`` is the whole file."""
    found: list[tuple[mi.StructType, str]] = []
    seen: set[type[Any]] = set()

    def visit(info: mi.Type, path: str) -> None:
        if isinstance(info, mi.Metadata):
            visit(info.type, path)
        elif isinstance(info, mi.UnionType):
            for member in info.types:
                visit(member, path)
        elif isinstance(info, mi.ListType):
            visit(info.item_type, f"{path}[]")
        elif isinstance(info, mi.DictType):
            visit(info.value_type, f"{path}.NAME")
        elif isinstance(info, mi.StructType):
            found.append((info, path))
            if info.cls in seen:
                return
            seen.add(info.cls)
            for f in info.fields:
                if not _internal(f):
                    visit(f.type, f"{path}.{f.encode_name}" if path else f.encode_name)

    visit(mi.type_info(root), "")
    if not unique:
        return found
    first: dict[type[Any], tuple[mi.StructType, str]] = {}
    for struct, path in found:
        first.setdefault(struct.cls, (struct, path))
    return list(first.values())


def _anchor(label: str, path: str) -> str:
    """The heading's id as mkdocs and code hosts make it (lower case, punctuation gone)."""
    heading = f"{label} {path or 'top level'}"
    words = re.sub(r"[^\w\s-]", "", heading).strip().lower()
    return re.sub(r"[-\s]+", "-", words)


def _internal(f: mi.Field) -> bool:
    return isinstance(f.type, mi.Metadata) and bool((f.type.extra or {}).get("internal"))


def _description(f: mi.Field) -> str:
    if isinstance(f.type, mi.Metadata):
        return str((f.type.extra_json_schema or {}).get("description", ""))
    return ""


def _type(info: mi.Type, label: str, paths: dict[type[Any], str]) -> str:
    """``number > 0``, ``list of [`robots[]`](#...)``, ``string or null``..."""
    if isinstance(info, mi.Metadata):
        return _type(info.type, label, paths)
    if isinstance(info, mi.UnionType):
        return " or ".join(_type(t, label, paths) for t in info.types)
    if isinstance(info, mi.StructType):
        return f"[`{paths[info.cls]}`](#{_anchor(label, paths[info.cls])})"
    if isinstance(info, mi.ListType):
        item = _type(info.item_type, label, paths)
        return ("non-empty list of " if info.min_length else "list of ") + item
    if isinstance(info, mi.DictType):
        lead = "non-empty mapping" if info.min_length else "mapping"
        return f"{lead} of name to {_type(info.value_type, label, paths)}"
    if isinstance(info, mi.LiteralType):
        values = ", ".join(f"`{v}`" for v in info.values)
        return values if len(info.values) == 1 else f"one of {values}"
    if isinstance(info, mi.IntType | mi.FloatType):
        name = "integer" if isinstance(info, mi.IntType) else "number"
        return name + _bounds(info.ge, info.gt, info.le, info.lt)
    if isinstance(info, mi.StrType):
        return "non-empty string" if info.min_length else "string"
    if isinstance(info, mi.CustomType) and issubclass(info.cls, PurePath):
        return "path"
    simple = {mi.BoolType: "boolean", mi.NoneType: "null", mi.AnyType: "any"}
    return simple.get(type(info), type(info).__name__)


def _bounds(ge: float | None, gt: float | None, le: float | None, lt: float | None) -> str:
    low = (f"[{ge:g}", f">= {ge:g}") if ge is not None else None
    low = (f"({gt:g}", f"> {gt:g}") if gt is not None else low
    high = (f"{le:g}]", f"<= {le:g}") if le is not None else None
    high = (f"{lt:g})", f"< {lt:g}") if lt is not None else high
    if low and high:
        return f" in {low[0]}, {high[0]}"
    one = low or high
    return f" {one[1]}" if one else ""


def _default(f: mi.Field) -> str:
    if f.required:
        return "required"
    value = f.default_factory() if f.default is msgspec.NODEFAULT else f.default
    return f"`{_flow(value)}`"


def _flow(value: Any) -> str:
    """``value`` in YAML flow style; a Struct as the fields that differ from its defaults."""
    if isinstance(value, msgspec.Struct):
        fields = msgspec.structs.fields(value)
        changed = [
            (f.encode_name, getattr(value, f.name))
            for f in fields
            if f.required or getattr(value, f.name) != _field_default(f)
        ]
        return "{" + ", ".join(f"{k}: {_flow(v)}" for k, v in changed) + "}"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k}: {_flow(v)}" for k, v in value.items()) + "}"
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_flow(v) for v in value) + "]"
    if isinstance(value, PurePath):
        value = str(value)
    return msgspec.json.encode(value).decode()


def _field_default(f: msgspec.structs.FieldInfo) -> Any:
    return f.default_factory() if f.default is msgspec.NODEFAULT else f.default


def _plain(text: str) -> str:
    """Docstring markup as Markdown: Sphinx roles and double backticks as code."""
    return _ROLE.sub(_role, text).replace("``", "`")


def _role(m: re.Match[str]) -> str:
    target = m[1].rsplit(".", 1)[-1] if "~" in m[0] else m[1]
    return f"`{target}`"
