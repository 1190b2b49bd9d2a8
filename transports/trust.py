"""Revocation: a secure transport polls its trusted folder and takes in what changed.

Removing ``NAME.key`` from the team's directory of public certificates must not wait
for every robot to restart. Each transport loaded from a folder looks at the folder's
listing (names, sizes, modification times) every ``poll_s`` seconds, in a thread, and
reloads it when that changed: a removed or replaced key is refused from the next
handshake on and the links made with it are closed (:mod:`~btcap.transports.zmq_rules`);
a new key is admitted. A folder that does not load (a half-copied file) changes nothing
and is said once, with the reason, until it loads again.
"""

from __future__ import annotations

import asyncio
import os
from collections.abc import Callable
from pathlib import Path

from btcap.transports.log import get_logger
from btcap.transports.security import TeamKeys

__all__ = ["DEFAULT_POLL_S", "first_listing", "listing", "watch_trusted"]

log = get_logger(__name__)

DEFAULT_POLL_S = 2.0
"""How often a transport looks at its trusted folder: a removed key is refused and its
links closed within this (plus the reload, a few ms for a hundred keys)."""

Listing = tuple[tuple[str, int, int], ...]


def listing(folder: Path) -> Listing:
    """What of ``folder`` a change of keys changes: each certificate's name, size and
    modification time (an unreadable folder lists as empty: the reload says why)."""
    try:
        with os.scandir(folder) as entries:
            found = [
                (e.name, st.st_size, st.st_mtime_ns)
                for e in entries
                if e.name.endswith(".key") and (st := e.stat()) is not None
            ]
    except OSError:
        return ()
    return tuple(sorted(found))


def first_listing(trusted: object) -> Listing | None:
    """What a watcher compares with first: the folder as the keys were loaded, taken
    before loading them (a change in between is then seen, and loaded again), not when
    the watcher starts (a key removed in between would go unseen)."""
    if isinstance(trusted, (str, os.PathLike)):
        return listing(Path(trusted))
    folder = getattr(trusted, "folder", None)
    return listing(folder) if isinstance(folder, Path) else None


async def watch_trusted(
    system: str,
    folder: Path,
    poll_s: float,
    trust: Callable[[TeamKeys], None],
    seen: Listing | None = None,
) -> None:
    """Every ``poll_s`` seconds, if ``folder``'s listing changed since ``seen`` (by
    default: when the watch starts), load it (in a thread) and hand the new allow-list
    to ``trust`` (which may refuse it with a ValueError: said once, the old keys kept).
    Runs until cancelled."""
    if seen is None:
        seen = await asyncio.to_thread(listing, folder)
    problem = ""
    while True:
        await asyncio.sleep(poll_s)
        now = await asyncio.to_thread(listing, folder)
        if now == seen:
            continue
        seen = now
        try:
            team = await asyncio.to_thread(TeamKeys.load, folder)
            trust(team)
        except (OSError, ValueError) as exc:
            if str(exc) != problem:
                problem = str(exc)
                log.warning(
                    "transport.trusted_not_reloaded",
                    system=system,
                    detail=f"keys.trusted: {problem}: keeping the keys loaded before",
                )
            continue
        problem = ""
