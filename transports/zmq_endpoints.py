"""Names and addresses of the ZeroMQ transport: system ids, endpoints, a peer's hello.

Everything here is checked before a socket opens or a peer is admitted, and says in one
line what is wrong; it needs no pyzmq, so a settings file is checked without loading it.
"""

from __future__ import annotations

from typing import NamedTuple

from btcap.transports.base import BROADCAST

__all__ = [
    "SCHEMES",
    "NewcomerLimits",
    "check_endpoint",
    "check_id",
    "check_newcomer_args",
    "check_transport_args",
    "parse_hello",
]

SCHEMES = ("tcp://", "ipc://", "inproc://")


def check_id(system_id: str) -> str | None:
    """Why ``system_id`` cannot name a system, or None if it can."""
    if not system_id or system_id == BROADCAST or "/" in system_id:
        return "expected a non-empty id without '/' that is not '*'"
    raw = system_id.encode()
    if len(raw) > 240:  # a zmq routing id holds 255, with room for a connection suffix
        return "longer than 240 bytes"
    if raw[0] == 0:
        return "starts with a NUL byte (reserved for ids zmq makes up)"
    return None


def check_endpoint(endpoint: str, *, dial: bool) -> str | None:
    """Why ``endpoint`` cannot be bound (or, ``dial``: dialled by peers), or None.

    libzmq wraps a tcp port above 65535 round to another port and binds that, so a typo
    would listen where no peer looks: refused here, with the other malformed endpoints.
    """
    if not endpoint.startswith(SCHEMES):
        return "expected a tcp://, ipc:// or inproc:// endpoint"
    if not endpoint.startswith("tcp://"):
        return None if endpoint.partition("://")[2] else "expected a name after the scheme"
    host, colon, port = endpoint.removeprefix("tcp://").rpartition(":")
    if not colon or not host:
        return "expected tcp://HOST:PORT"
    if dial and (port == "*" or "*" in host):
        return "expected a host and port peers can dial, not a wildcard"
    if port != "*" and not (port.isdigit() and int(port) <= 65535):
        return f"port {port!r}: expected 0 to 65535" + ("" if dial else " or *")
    return None


def check_transport_args(system_id: str, bind: str, advertise: str | None, max_bytes: int) -> None:
    """What a ZmqTransport is given, checked before any socket opens."""
    if (why := check_id(system_id)) is not None:
        raise ValueError(f"system id {system_id!r}: {why}")
    if (why := check_endpoint(bind, dial=False)) is not None:
        raise ValueError(f"cannot bind {bind!r}: {why}")
    if advertise is not None and (why := check_endpoint(advertise, dial=True)) is not None:
        raise ValueError(f"advertise {advertise!r}: {why}")
    if max_bytes < 1024:
        raise ValueError(f"max_message_bytes {max_bytes}: expected at least 1024")


class NewcomerLimits(NamedTuple):
    """How long an inbound connection may stay silent, how many may wait for their hello
    at once, and how many links a peer keeps (:mod:`~btcap.transports.newcomers`)."""

    hello_timeout_s: float
    max_newcomers: int
    links_per_peer: int


def check_newcomer_args(
    hello_timeout_s: float, max_newcomers: int, links_per_peer: int
) -> NewcomerLimits:
    """The limits, checked: the first two > 0, and at least 2 links per peer (one that
    relinks holds two for a moment)."""
    if not (hello_timeout_s > 0 and max_newcomers > 0):
        what = f"hello_timeout_s={hello_timeout_s}, max_newcomers={max_newcomers}"
        raise ValueError(f"{what}: expected both > 0")
    if links_per_peer < 2:
        raise ValueError(
            f"links_per_peer={links_per_peer}: expected at least 2 (a peer that relinks "
            "holds two links for a moment)"
        )
    return NewcomerLimits(hello_timeout_s, max_newcomers, links_per_peer)


def parse_hello(ident: bytes, payload: bytes, own_id: str) -> tuple[str, str]:
    """The peer id and endpoint a hello announces; ValueError says what is wrong."""
    try:
        peer = ident.decode()
        endpoint = payload.decode()
    except UnicodeDecodeError:
        raise ValueError("id or endpoint not UTF-8") from None
    if (why := check_id(peer)) is not None:
        raise ValueError(why)
    if not endpoint.startswith(SCHEMES) or len(endpoint) > 1024:
        raise ValueError(f"endpoint {endpoint[:80]!r}")
    if peer == own_id:
        raise ValueError("another system uses our id")
    return peer, endpoint
