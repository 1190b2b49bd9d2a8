"""Reading a tree file's text into a checked :class:`~btcap.bt.files.schema.TreeFile`.

Parser and schema errors are translated to say where: the file, a line for malformed
text, and for schema errors the node path (from the raw document) and the field.
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any

import msgspec
import msgspec.json
import msgspec.yaml
import yaml

from btcap.bt.files.schema import (
    SCHEMA_VERSION,
    STRUCT_FIELDS,
    Format,
    SubtreeSpec,
    TreeFile,
    TreeFileError,
)

__all__ = ["decode", "format_of", "parse", "read_bytes", "read_tree_file"]

_SUFFIXES: dict[str, Format] = {".yaml": "yaml", ".yml": "yaml", ".json": "json"}


def format_of(path: Path) -> Format:
    """YAML or JSON by suffix; a file of any other kind is refused by name."""
    fmt = _SUFFIXES.get(path.suffix.lower())
    if fmt is None:
        raise TreeFileError(
            [
                f"{path}: unknown file type {path.suffix or '(none)'!r}; "
                f"expected .yaml, .yml or .json (or .xml to load BehaviorTree.CPP v4 XML)"
            ]
        )
    return fmt


def decode(text: bytes | str, fmt: Format, where: str) -> Any:
    """Plain data from text; malformed text and duplicate YAML keys are named by line."""
    try:
        if fmt == "json":
            return msgspec.json.decode(text)
        raw = msgspec.yaml.decode(text)
        dups = _yaml_duplicates(text)
    except (msgspec.DecodeError, yaml.YAMLError) as exc:
        raise TreeFileError(
            [f"{where}: malformed {fmt.upper()}: {_decode_detail(str(exc), text)}"]
        ) from None
    if dups:
        raise TreeFileError(f"{where}: {d}" for d in dups)
    return raw


_Loader: type[yaml.SafeLoader] = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def _yaml_duplicates(text: bytes | str) -> list[str]:
    """YAML silently keeps the last of two equal keys; a tree file must not."""
    out: list[tuple[int, str]] = []
    stack = [yaml.compose(text, Loader=_Loader)]
    while stack:
        node = stack.pop()
        if isinstance(node, yaml.MappingNode):
            seen: set[str] = set()
            for key, value in node.value:
                if isinstance(key, yaml.ScalarNode):
                    if key.value in seen:
                        line = key.start_mark.line + 1
                        out.append((line, f"line {line}: duplicate key {key.value!r}"))
                    seen.add(key.value)
                stack.append(value)
        elif isinstance(node, yaml.SequenceNode):
            stack.extend(node.value)
    return [f"{msg} (YAML would silently keep only the last one)" for _, msg in sorted(out)]


def _decode_detail(msg: str, text: bytes | str) -> str:
    """Make parser messages point at a line: YAML's marks, JSON's byte offsets."""
    msg = msg.replace('in "<unicode string>", ', "").replace('in "<byte string>", ', "")
    msg = msg.removeprefix("JSON is malformed: ")
    msg = "; ".join(part.strip() for part in msg.splitlines() if part.strip())
    m = re.search(r"\(byte (\d+)\)", msg)
    if m:
        data = text.encode() if isinstance(text, str) else text
        offset = int(m.group(1))
        line = data.count(b"\n", 0, offset) + 1
        col = offset - (data.rfind(b"\n", 0, offset) + 1) + 1
        msg = msg.replace(m.group(0), f"(line {line}, column {col})")
    return msg


def parse(raw: Any, where: str) -> TreeFile:
    """Check the version, then convert to :class:`TreeFile`, translating error paths."""
    if raw is None:
        raise TreeFileError(
            [f"{where}: the file is empty; expected a btcap tree (btcap: 1, root: ...)"]
        )
    if not isinstance(raw, dict):
        raise TreeFileError(
            [f"{where}: top level: expected a mapping with btcap, root, ..., got {_kind(raw)}"]
        )
    version = raw.get("btcap")
    if "btcap" not in raw:
        raise TreeFileError(
            [f"{where}: field 'btcap': missing; a tree file starts with 'btcap: {SCHEMA_VERSION}'"]
        )
    if isinstance(version, bool) or version != SCHEMA_VERSION:
        raise TreeFileError(
            [
                f"{where}: field 'btcap': unsupported schema version {version!r}; this btcap "
                f"reads version {SCHEMA_VERSION}"
            ]
        )
    problems: list[str] = []
    subtrees: dict[str, SubtreeSpec] = {}
    raw_subs = raw.get("subtrees")
    if isinstance(raw_subs, dict):
        for key, value in raw_subs.items():
            if not isinstance(key, str):
                continue  # reported by the whole-file conversion below
            label = f"subtree {key!r} "
            try:
                sub = msgspec.convert(value, SubtreeSpec)
            except msgspec.ValidationError as exc:
                problems.append(_translate(str(exc), value, "subtree", where, label))
                continue
            if (sub.file is None) == (sub.root is None):
                problems.append(
                    f"{where}: {label}field 'root': give either 'root' (an inline tree) or "
                    f"'file' (a path to a tree file), not {'both' if sub.file else 'neither'}"
                )
            elif sub.file is not None and (sub.wires or sub.public or sub.description):
                problems.append(
                    f"{where}: {label}field 'file': a subtree from a file takes no wires, "
                    f"public or description here (the other file has its own)"
                )
            else:
                subtrees[key] = sub
        raw = {**raw, "subtrees": {k: {"file": "-"} for k in raw_subs}}
    try:
        spec = msgspec.convert(raw, TreeFile)
    except msgspec.ValidationError as exc:
        problems.append(_translate(str(exc), raw, "file", where, ""))
        raise TreeFileError(problems) from None
    if problems:
        raise TreeFileError(problems)
    return msgspec.structs.replace(spec, subtrees=subtrees)


def _kind(value: Any) -> str:
    for cls, word in ((dict, "a mapping"), (list, "a list"), (str, "a string")):
        if isinstance(value, cls):
            return word
    return type(value).__name__


_STEP = re.compile(r"\.([^.\[]+)|\[(\d+|\.\.\.)\]")


def _translate(msg: str, raw: Any, kind: str, where: str, label: str) -> str:
    """Turn ``Expected `int`, got `str` - at `$.root.children[1].name``` into a node path."""
    text, _, loc = msg.partition(" - at `")
    loc = loc.rstrip("`")
    is_key = loc.startswith("key` in `")
    if is_key:
        loc = loc[len("key` in `") :]
    steps: list[str | int] = []
    for m in _STEP.finditer(loc.removeprefix("$")):
        if m.group(1) is not None:
            steps.append(m.group(1))
        else:
            steps.append(int(m.group(2)) if m.group(2).isdigit() else "[...]")
    node_path: list[str] = []
    cur: Any = raw
    struct = kind  # the schema struct the error location is in, for listing its fields
    field: list[str | int] = []
    i = 0
    while i < len(steps):
        step = steps[i]
        nxt = steps[i + 1] if i + 1 < len(steps) else None
        last = i + 1 == len(steps)
        if struct in ("file", "subtree") and step == "root":
            cur = _get(cur, "root")
            node_path = [_raw_name(cur, "root")]
            struct = "node"
            i += 1
        elif struct == "node" and step == "children" and isinstance(nxt, int):
            cur = _get(_get(cur, "children"), nxt)
            node_path.append(_raw_name(cur, f"[{nxt}]"))
            i += 2
        elif struct in ("file", "subtree") and step == "wires" and isinstance(nxt, int):
            field = ["wires", nxt]
            struct = "wire"
            i += 2
        elif struct in ("file", "subtree") and step == "public" and last:
            field = ["public"]
            struct = "public"
            i += 1
        else:
            field.extend(steps[i:])
            struct = ""
            break
    name = "".join(
        f"[{s}]" if isinstance(s, int) else s if s == "[...]" else f".{s}" for s in field
    ).lstrip(".")
    parts = [label.strip()] if label else []
    if node_path:
        parts.append(f"node {'/'.join(node_path)!r}")
    if name:
        parts.append(f"{'key of ' if is_key else ''}field {name!r}")
    elif not parts:
        parts.append("top level")
    return f"{where}: {' '.join(parts)}: {_reword(text, struct)}"


def _reword(text: str, struct: str) -> str:
    m = re.match(r"Object contains unknown field `(.+)`$", text)
    if m:
        known = STRUCT_FIELDS.get(struct)
        near = f"; expected one of {', '.join(known)}" if known else ""
        return f"unknown field {m.group(1)!r}{near}"
    m = re.match(r"Object missing required field `(.+)`$", text)
    if m:
        return f"missing required field {m.group(1)!r}"
    text = text.replace("`", "")
    return text[:1].lower() + text[1:]


def _get(value: Any, key: str | int) -> Any:
    try:
        return value[key]
    except (KeyError, IndexError, TypeError):
        return None


def _raw_name(node: Any, fallback: str) -> str:
    if isinstance(node, dict):
        name = node.get("name")
        if isinstance(name, str | int | float):
            return str(name)
        if name is None and isinstance(node.get("type"), str):
            return str(node["type"])
    return fallback


def read_tree_file(path: str | os.PathLike[str]) -> TreeFile:
    """Read and schema-check a file without building nodes (no registry needed)."""
    p = Path(path)
    return parse(decode(read_bytes(p), format_of(p), str(p)), str(p))


def read_bytes(path: Path) -> bytes:
    try:
        return path.read_bytes()
    except OSError as exc:
        raise TreeFileError([f"{path}: cannot read: {exc.strerror or exc}"]) from None
