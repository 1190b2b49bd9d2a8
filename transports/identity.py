"""Who a peer is: a member's role, and the ids of observers that are not members.

A member's **role** (:data:`ROLES`) says what it may send (the table lives with the
protocol, :mod:`btcap.team.membership.roles`). With keys it is written in the member's certificate
(``btcap keys new NAME --role ROLE``), under ZeroMQ's ``metadata`` section::

    metadata
        name = "alpha"
        role = "robot"
    curve
        public-key = "..."

An **observer** (``btcap team status``) asks the team but never joins it. It runs under
an id of its own, the member it speaks for, a ``+`` and a tag (``operator+status-1a2b``),
so it never takes the member's place; with keys it authenticates with that member's key,
and its role is ``observer`` whatever its key's. Member names therefore never hold ``+``.
"""

from __future__ import annotations

import os
import secrets
from pathlib import Path

__all__ = [
    "OBSERVER",
    "OPERATOR",
    "ROBOT",
    "ROLES",
    "check_member_name",
    "check_role",
    "is_observer_id",
    "member_of",
    "observer_id",
    "read_role",
]

ROBOT = "robot"
"""Bids, runs work, reports on it; may also run missions (any robot can be an origin)."""
OPERATOR = "operator"
"""Runs missions (auctions, awards, inputs, cancels) and asks; never bids or executes."""
OBSERVER = "observer"
"""Only asks: never a member, never counted, bid to, awarded or asked to vouch."""
ROLES = (ROBOT, OPERATOR, OBSERVER)
_SEP = "+"


def observer_id(member: str, tag: str = "observer") -> str:
    """A fresh id for an observer speaking for ``member`` (``member+tag-1a2b3c``)."""
    return f"{member}{_SEP}{tag}-{secrets.token_hex(3)}"


def is_observer_id(system_id: str) -> bool:
    return _SEP in system_id


def member_of(system_id: str) -> str:
    """The member an id speaks for: itself, or the member an observer id names."""
    return system_id.partition(_SEP)[0]


def check_member_name(name: str) -> str | None:
    """Why ``name`` cannot be a member's (robot's) name, or None."""
    if _SEP in name:
        return f"contains {_SEP!r} (reserved for observers' ids: NAME{_SEP}TAG)"
    return None


def check_role(role: str, where: str) -> str:
    if role not in ROLES:
        raise ValueError(f"{where}: role {role!r}: expected one of {', '.join(ROLES)}")
    return role


def read_role(path: str | os.PathLike[str]) -> str:
    """The ``role`` in a certificate's ``metadata`` section (ZeroMQ's ZPL format, which
    pyzmq writes but does not read back). A key made before roles existed has none: that
    is an error naming the file and the fix, never a silent default."""
    file = Path(path)
    section = ""
    role: str | None = None
    for raw in file.read_text(encoding="utf-8", errors="replace").splitlines():
        line = raw.split("#", 1)[0].rstrip()
        if not line.strip():
            continue
        if not line[0].isspace():
            section = line.strip()
            continue
        key, eq, value = line.strip().partition("=")
        if section == "metadata" and eq and key.strip() == "role":
            role = value.strip().strip("'\"")
    if role is None:
        raise ValueError(
            f"{file}: no role in its metadata (a key made before roles): make a new pair "
            f"with 'btcap keys new {file.stem} --role {'|'.join(ROLES)}', or add the line "
            f"'    role = \"robot\"' under 'metadata'"
        )
    return check_role(role, str(file))
