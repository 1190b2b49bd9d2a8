"""Which addresses count as this machine only."""

from __future__ import annotations

import ipaddress

__all__ = ["LOCAL_NAMES", "is_loopback"]

#: The names a request to this machine gives as its ``Host`` (without the port).
LOCAL_NAMES = frozenset({"127.0.0.1", "localhost", "[::1]"})


def is_loopback(host: str) -> bool:
    """``localhost`` or a loopback address (a name that resolves elsewhere is not)."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False
