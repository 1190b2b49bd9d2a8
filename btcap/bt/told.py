"""A node's first error, told by default: a :class:`~btcap.bt.state.NodeErrorWarning`.

The error is logged (``btcap.node_error``) every time, but a program that configured no
logging would never see it, and a Fallback above the node may still let the tree
succeed. So the first error of each node of a tree is also a warning, which Python shows
by default and the standard filters quieten
(``warnings.filterwarnings("ignore", category=btcap.NodeErrorWarning)``). The warning
points at the line that raised, so the usual ``file:line`` leads to the bug.
"""

from __future__ import annotations

import warnings
from typing import Protocol

from btcap.bt.host import TreeHost
from btcap.bt.state import NodeErrorWarning

__all__ = ["tell_error"]


class _Node(Protocol):
    """What telling needs of a :class:`~btcap.bt.node.Node` (which imports this module)."""

    _tree: TreeHost | None

    @property
    def path(self) -> str: ...


#: The longest exception text a warning repeats (a peer's or a file's text can be long).
_TEXT = 300


def tell_error(node: _Node, exc: BaseException, action: str) -> None:
    """Warn about ``node``'s error in ``action`` unless its tree already told one of it.

    A filter may turn the warning into an error: it then leaves the tick unchanged (the
    nodes above raise it on, see ``Node._fail``).
    """
    tree = node._tree
    path = node.path
    if tree is not None:
        if path in tree._told:
            return
        tree._told.add(path)
    text = str(exc)
    if len(text) > _TEXT:
        text = text[:_TEXT] + "..."
    message = (
        f"node {path!r} ({type(node).__name__}) raised {type(exc).__name__} in {action}: "
        f"{text}; it is in ERROR now, and its parent decides what follows (a Fallback may "
        "still succeed). Fix the code that raised, or report a failure you expect as one "
        "(return FAILED; an Action's function returns False); later errors of this node "
        "go to the log only (logger 'btcap')"
    )
    tb = exc.__traceback__
    if tb is None:  # refused by btcap itself (an input a port's constraint refuses)
        warnings.warn_explicit(message, NodeErrorWarning, f"<node {path}>", 0, module="btcap")
        return
    while tb.tb_next is not None:
        tb = tb.tb_next
    frame = tb.tb_frame
    where = frame.f_globals
    warnings.warn_explicit(
        message,
        NodeErrorWarning,
        frame.f_code.co_filename,
        tb.tb_lineno,
        module=where.get("__name__", "btcap"),
        registry=where.setdefault("__warningregistry__", {}),
    )
