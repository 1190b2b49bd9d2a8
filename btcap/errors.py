"""The base of every error btcap raises on purpose.

``except BtcapError`` catches what btcap itself reports (a bad file, a refused message,
a timed-out request) and lets programming errors through. Each error keeps its builtin
base too (``ValueError``, ``TimeoutError`` ...), so existing ``except`` clauses still
catch it. This module imports nothing of btcap: every layer may use it.
"""

from __future__ import annotations

__all__ = ["BtcapError", "BtcapWarning", "HandshakeWarning"]


class BtcapError(Exception):
    """An error btcap raises on purpose; its message says what was wrong and where."""


class BtcapWarning(UserWarning):
    """Base class of btcap's warnings, to filter them all at once (here, below every
    layer, so the transports' warnings have it too)."""


class HandshakeWarning(BtcapWarning):
    """A handshake failed (a key refused, by either side; keys on one side only; a stale
    copy of a key): said once per peer or key of a transport, naming what to check (see
    :mod:`btcap.transports.refusals`). Here, not there, so the commands can quieten it
    without loading the transports for ``--help``."""
