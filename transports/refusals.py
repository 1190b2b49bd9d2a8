"""Failed handshakes, told to the person who can fix them, on both machines.

A key the team does not trust, a robot without keys in a keyed team (or the other way
round) or a stale copy of a teammate's public key make libzmq fail the handshake before
any message flows, so both robots would wait in silence. libzmq tells a socket monitor
(and the refused key to the ZAP handler, with the peer's address); :class:`Refusals`
turns that into one warning per peer, again at most every ``quiet_s`` while it lasts,
naming the key file and the config field to check, and paces the re-dials of a link that
failed (libzmq gives up on a refused one; re-dialling at once would be a storm).

Those lines are log records, which a program that configured no logging never sees
(btcap's loggers end in a NullHandler), so the first of each peer or key is also a
:class:`HandshakeWarning`, which Python shows by default and
``warnings.filterwarnings("ignore", category=btcap.HandshakeWarning)`` quietens (the
``btcap`` commands do: their log shows it).
"""

from __future__ import annotations

import contextlib
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass

import zmq

from btcap.errors import HandshakeWarning
from btcap.transports.base import TransportStats
from btcap.transports.log import get_logger

__all__ = [
    "FAILED",
    "HANDSHAKE_EVENTS",
    "REFUSED",
    "SUCCEEDED",
    "HandshakeWarning",
    "Refusals",
    "fingerprint",
]

log = get_logger(__name__)

REFUSED = int(zmq.EVENT_HANDSHAKE_FAILED_AUTH)
FAILED = int(zmq.EVENT_HANDSHAKE_FAILED_PROTOCOL)
NO_DETAIL = int(zmq.EVENT_HANDSHAKE_FAILED_NO_DETAIL)
SUCCEEDED = int(zmq.EVENT_HANDSHAKE_SUCCEEDED)
HANDSHAKE_EVENTS = REFUSED | FAILED | NO_DETAIL | SUCCEEDED
"""What a dialling socket's monitor watches besides disconnects."""

_MISMATCH = int(zmq.PROTOCOL_ERROR_ZMTP_MECHANISM_MISMATCH)
_CRYPTOGRAPHIC = int(zmq.PROTOCOL_ERROR_ZMTP_CRYPTOGRAPHIC)
_UNCLEAR_TRIES = 3
"""Handshakes that fail without a reason (a server not serving yet does that too) before
one is worth a warning."""
_FIRST_RETRY_S = 0.25
_MAX_RETRY_S = 30.0


def fingerprint(key: bytes) -> str:
    """A z85 public key shortened for a log line: enough to tell keys apart by eye."""
    text = key.decode(errors="replace")
    return f"{text[:8]}\u2026" if len(text) > 8 else text  # (z85 has dots of its own)


@dataclass(slots=True)
class _Seen:
    count: int = 0
    logged_at: float = -1e18
    logged_count: int = 0


class Refusals:
    """One transport's failed handshakes: the peers that refused us (also kept in
    :attr:`TransportStats.refused_by` until one admits us) and those we refused.

    ``own_key`` is our public key (None without keys). The table of what was seen keeps
    at most ``max_entries`` peers and keys: anyone can present any number of keys.
    """

    def __init__(
        self,
        system: str,
        stats: TransportStats,
        own_key: bytes | None,
        *,
        quiet_s: float = 60.0,
        max_entries: int = 256,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.system = system
        self.stats = stats
        self.own_key = own_key
        self.quiet_s = quiet_s
        self.max_entries = max_entries
        self.clock = clock
        self._seen: dict[str, _Seen] = {}
        self._failures: dict[str, int] = {}
        self._warned: dict[str, None] = {}  # what was a warning (bounded as _seen)

    def _warn(self, what: str, why: str, event: str) -> None:
        """The first time of ``what``: a :class:`HandshakeWarning` too (see the module)."""
        if what in self._warned:
            return
        self._warned[what] = None
        while len(self._warned) > self.max_entries:
            del self._warned[next(iter(self._warned))]
        text = (
            f"{self.system}: {why} (said once; logged as {event} while it lasts, logger "
            "'btcap.transports.refusals')"
        )
        with contextlib.suppress(HandshakeWarning):  # made an error by a filter: logged
            warnings.warn_explicit(text, HandshakeWarning, "<btcap handshake>", 0, module="btcap")

    def _worth_a_line(self, what: str) -> int:
        """How many times ``what`` happened since its last line, if it deserves one now
        (the first time, then at most every ``quiet_s``); 0 if not."""
        seen = self._seen.pop(what, None) or _Seen()
        self._seen[what] = seen  # the most recent last: the oldest goes when full
        while len(self._seen) > self.max_entries:
            del self._seen[next(iter(self._seen))]
        seen.count += 1
        now = self.clock()
        if now - seen.logged_at < self.quiet_s:
            return 0
        since, seen.logged_at, seen.logged_count = seen.count - seen.logged_count, now, seen.count
        return since

    # -- the dialling side ----------------------------------------------------------------
    def failed(self, peer: str, endpoint: str, event: int, value: int) -> float:
        """A handshake with ``peer`` failed (a monitor's ``event`` and its value): said
        when it deserves a line; returns the seconds to wait before dialling again."""
        n = self._failures.get(peer, 0) + 1
        self._failures[peer] = n
        while len(self._failures) > self.max_entries:
            del self._failures[next(iter(self._failures))]
        why = self._why_failed(peer, endpoint, event, value, n)
        if why is not None:
            told = self.stats.refused_by
            told.pop(peer, None)
            told[peer] = why  # the most recent last: the oldest goes when full
            while len(told) > self.max_entries:
                del told[next(iter(told))]
            if times := self._worth_a_line(f"peer {peer}"):
                ours = {} if self.own_key is None else {"our_key": fingerprint(self.own_key)}
                log.warning(
                    "transport.handshake_refused",
                    system=self.system,
                    peer=peer,
                    endpoint=endpoint,
                    detail=why,
                    count=times,
                    **ours,
                )
                self._warn(f"peer {peer}", why, "transport.handshake_refused")
        return min(_MAX_RETRY_S, _FIRST_RETRY_S * 2.0 ** min(n - 1, 16))

    def _why_failed(self, peer: str, endpoint: str, event: int, value: int, n: int) -> str | None:
        me, keyed = self.system, self.own_key is not None
        if event == REFUSED and value == 400:
            return (
                f"{peer} refused our key: is {me}.key in its trusted folder "
                f"(keys.trusted in {peer}'s config file)?"
            )
        if event == REFUSED:
            return f"{peer} could not check our key (ZAP status {value}); trying again"
        if event == FAILED and value == _MISMATCH and keyed:
            return (
                f"{peer} at {endpoint} has no keys and we have: a team is keyed or not, "
                f"all of it (keys: in {peer}'s config file)"
            )
        add_keys = (
            f"add keys: {{secret: {me}.key_secret, trusted: DIR}} to our config file "
            f"(btcap keys new {me}), and {me}.key to the team's trusted folders"
        )
        if event == FAILED and value == _MISMATCH:
            return f"{peer} at {endpoint} wants keys and we have none: {add_keys}"
        if event == FAILED:
            return f"the handshake with {peer} at {endpoint} failed (zmq error {value:#x})"
        if event != NO_DETAIL or n < _UNCLEAR_TRIES:
            return None
        if not keyed:  # (it hung up before saying why: only a keyed robot does that)
            return f"{peer} at {endpoint} wants keys, it seems, and we have none: {add_keys}"
        return (
            f"no handshake with {peer} at {endpoint} after {n} tries: has {peer} keys, "
            f"and does {peer}.key in our trusted folder (keys.trusted) hold its current one?"
        )

    def admitted(self, peer: str) -> None:
        """A handshake with ``peer`` succeeded: it is no longer refusing us."""
        self._failures.pop(peer, None)
        if self.stats.refused_by.pop(peer, None) is not None:
            self._seen.pop(f"peer {peer}", None)
            log.info("transport.handshake_admitted", system=self.system, peer=peer)

    # -- the listening side ---------------------------------------------------------------
    def we_refused(self, address: str, key: bytes, known_as: str | None = None) -> None:
        """Our ZAP handler refused the z85 ``key`` a peer at ``address`` presented."""
        fp = fingerprint(key)
        if not (times := self._worth_a_line(f"key {key.decode(errors='replace')}")):
            return
        if known_as is None:
            why = (
                f"refused {address}: its key {fp} is not in our trusted folder "
                "(keys.trusted): if it is a teammate, add its NAME.key there (read within 2 s)"
            )
        else:
            why = f"refused {address}: its key {fp} is {known_as}'s, not allowed here"
        log.warning(
            "transport.key_refused",
            system=self.system,
            address=address,
            key=fp,
            known_as=known_as or "unknown",
            detail=why,
            count=times,
        )
        self._warn(f"key {key.decode(errors='replace')}", why, "transport.key_refused")

    def handshake_failed(self, value: int) -> None:
        """A peer failed the handshake with us (libzmq tells no address for this)."""
        self.stats.drop("handshake failed")
        if not (times := self._worth_a_line(f"failed {value}")):
            return
        me = self.system
        if value == _MISMATCH and self.own_key is not None:
            why = "a peer without keys tried to connect: a keyed team admits only keyed robots"
        elif value == _MISMATCH:
            why = (
                "a peer with keys tried to connect and we have none: add keys: to our "
                "config file (btcap keys new), or remove them from its"
            )
        elif value == _CRYPTOGRAPHIC:
            why = (
                f"a peer failed the key exchange: it may dial us with an old copy of our "
                f"public key ({me}.key in its trusted folder)"
            )
        else:
            why = f"a peer failed the handshake (zmq error {value:#x})"
        log.warning("transport.handshake_failed", system=me, detail=why, count=times)
        self._warn(f"failed {value}", why, "transport.handshake_failed")
