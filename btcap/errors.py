"""The base of every error btcap raises on purpose.

``except BtcapError`` catches what btcap itself reports (a bad file, a refused message,
a timed-out request) and lets programming errors through. Each error keeps its builtin
base too (``ValueError``, ``TimeoutError`` ...), so existing ``except`` clauses still
catch it. This module imports nothing of btcap: every layer may use it.
"""

from __future__ import annotations

__all__ = ["BtcapError", "BtcapWarning"]


class BtcapError(Exception):
    """An error btcap raises on purpose; its message says what was wrong and where."""


class BtcapWarning(UserWarning):
    """Base class of btcap's warnings, to filter them all at once (here, below every
    layer, so the transports' warnings have it too)."""
