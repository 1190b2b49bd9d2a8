"""Values from the wire back to their ports' declared types, named in errors only when
one is wrong (every call for bids converts its inputs on every robot it reaches)."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import msgspec

from btcap.bt.ports import PortMap, check_value

__all__ = ["Where", "convert"]

#: What a conversion names in its errors: the text, or a function making it (called
#: only for an error).
Where = str | Callable[[], str]


def convert(ports: PortMap, values: Mapping[str, Any], where: Where, kind: str) -> dict[str, Any]:
    """``values`` by port (missing ones: None), each converted to its port's type and
    held to its constraints (a port's ``Meta``: a peer's value is no more trusted than a
    tree file's) as :func:`~btcap.bt.ports.check_port` does (inline: the text naming a
    value is made, and check_value called for its error, only when the conversion
    fails)."""
    out: dict[str, Any] = {}
    for key, port in ports.items():
        value = values.get(key)
        t = port.checked
        if value is None or t is Any:
            out[key] = value
            continue
        try:
            out[key] = msgspec.convert(value, t, strict=False)
        except (msgspec.ValidationError, TypeError):
            named = where() if callable(where) else where
            # raises, saying why
            out[key] = check_value(value, port.type, f"{named} {kind} {key!r}", port.meta)
    return out
