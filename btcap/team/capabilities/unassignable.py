"""A capability nobody can take, told by default: an :class:`~btcap.bt.state.UnassignableWarning`.

The capability node logs its empty auctions (``capability.unassigned``), but a program
that configured no logging would see a mission wait for ever in silence. So the first
empty auction that was not about busy robots (an award declined for good, such as a
setup that fails at every award, is not about a busy robot), and the end of an
``assignment_timeout_s``, are also warnings, once per node of a tree: Python shows them
by default, and ``warnings.filterwarnings("ignore", category=btcap.UnassignableWarning)``
quietens them.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from typing import Protocol

from btcap.bt.host import TreeHost
from btcap.bt.state import UnassignableWarning

__all__ = ["Told", "nobody_able", "tell_nobody", "tell_once", "tell_timeout"]

#: Reasons that say a robot could take the work but not now (routine while a team is
#: busy): it was busy, took another task of the same round, kept its own work, did not
#: answer (yet), bid at or above the reserve, or declined the award.
_NOT_NOW = (
    "busy",
    "took another task",
    "kept its work",
    "no claim",
    "no answer",
    "not below",
    "declined the award",
)


class Told(Protocol):
    """What telling needs of a :class:`~btcap.team.capabilities.capability.Capability`."""

    _tree: TreeHost | None

    @property
    def path(self) -> str: ...


#: What an award declined for good says (its robot bids, wins and declines again at every
#: auction: not a robot that is only occupied): its implementation's setup failed, the
#: lease is over its max_lease_s, its clock runs at another speed-up, it cannot run these
#: inputs, or it lacks the implementation or a remote capability slot.
_FOR_GOOD = (
    "setup of ",
    "max_lease_s",
    "clock speed-up",
    "cannot execute",
    "no implementation",
    "no remote capability slot",
)


def _not_now(text: str) -> bool:
    if text.startswith("declined the award") and any(m in text for m in _FOR_GOOD):
        return False
    return any(marker in text for marker in _NOT_NOW)


def nobody_able(why: Mapping[str, str]) -> bool:
    """Whether an empty auction's reasons (robot -> why) say that nobody in the team can
    take the work at all, rather than that the robots able to are occupied."""
    return not any(_not_now(text) for text in why.values())


def tell_nobody(node: Told, interface: str, why: Mapping[str, str], timeout_s: float) -> None:
    """Nobody could take ``node``: each robot's reason in ``why``; ``timeout_s``: its
    ``assignment_timeout_s`` (0: it waits for ever)."""
    reasons = "; ".join(f"{robot}: {text}" for robot, text in sorted(why.items()))
    then = (
        f"; it fails after {timeout_s:g} s unassigned (its assignment_timeout_s)"
        if timeout_s > 0
        else ", or set assignment_timeout_s on the node to fail after a wait"
    )
    tell_once(
        node,
        "nobody",
        f"capability {node.path!r} ({interface}): nobody in the team can take it "
        f"({reasons or 'no robot answered'}). It waits unassigned and tries again when "
        f"the team changes; fix what the reasons name{then}",
    )


def tell_timeout(node: Told, interface: str, timeout_s: float, auctions: int) -> None:
    """``node`` waited its ``assignment_timeout_s`` and failed."""
    tell_once(
        node,
        "timeout",
        f"capability {node.path!r} ({interface}) failed: nobody took it within its "
        f"assignment_timeout_s of {timeout_s:g} s ({auctions} auction"
        f"{'' if auctions == 1 else 's'} found nobody free and able); its parent decides "
        "what follows",
    )


def tell_once(
    node: Told,
    what: str,
    message: str,
    category: type[Warning] = UnassignableWarning,
) -> None:
    """Warn once per node of a tree and ``what`` (later ones go to the log only)."""
    tree = node._tree
    key = f"{node.path} {what}"
    if tree is not None:
        if key in tree._told:
            return
        tree._told.add(key)
    where = f"<capability {node.path}>"
    warnings.warn_explicit(message, category, where, 0, module="btcap")
