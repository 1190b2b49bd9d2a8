"""``btcap tree show`` and ``btcap tree dot``: a loaded tree as an outline or a picture.

Apart from :mod:`btcap.cli.tree` so that ``btcap --help`` never imports rendering. A
BehaviorTree.CPP file's entries are shown too: each node's ports using one, and the
entries read before any node writes them (:mod:`btcap.bt.files.btcpp_uses`).
"""

from __future__ import annotations

import sys
from pathlib import Path

from btcap.bt.files import file_info
from btcap.bt.files.btcpp_uses import entry_uses
from btcap.bt.render import render_dot, render_text
from btcap.bt.tree import Tree
from btcap.cli import CliError
from btcap.cli.graphviz import PICTURES, graphviz

__all__ = ["dot", "show"]

_HEADINGS = (
    (False, "blackboard entries to set before ticking (read before any node writes them):"),
    (True, "blackboard entries nobody sets (a subtree reads them, its SubTree passes none):"),
)


def show(tree: Tree) -> int:
    """The outline, then the entries to set before ticking."""
    info = file_info(tree)
    if info.description:
        print(info.description)
    uses = entry_uses(tree)
    sys.stdout.write(render_text(tree, entries=uses.lines if uses else None))
    needed = uses.needed(tree.name) if uses else []
    for unset, heading in _HEADINGS:
        some = [n for n in needed if bool(n.via) is unset]
        if some:
            print(heading)
        for need in some:
            print(f"  {need.describe()} (line {need.line})")
    return 0


def dot(tree: Tree, out: Path | None) -> int:
    """DOT on stdout, or a file (a picture by its suffix); entries to set in a note."""
    uses = entry_uses(tree)
    needed = uses.needed(tree.name) if uses else []
    note = ["blackboard entries read before any node writes them:"]
    note += [n.describe() for n in needed]
    text = render_dot(tree, entries=uses.lines if uses else None, note=note if needed else ())
    if out is None:
        sys.stdout.write(text)
        return 0
    picture = PICTURES.get(out.suffix.lower())
    try:
        if picture is None:
            out.write_text(text, encoding="utf-8")
        else:
            out.write_bytes(graphviz(text, picture))
    except OSError as exc:
        raise CliError(f"{out}: cannot write: {exc.strerror or exc}") from None
    print(f"wrote {out}", file=sys.stderr)
    return 0
