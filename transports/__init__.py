"""Moving typed envelopes between actor systems: codec, in-process and ZeroMQ transports."""

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from btcap.transports.base import BROADCAST, Deliver, Transport, TransportStats
    from btcap.transports.codec import Codec, CodecError, Envelope, Kind
    from btcap.transports.inprocess import InProcessNetwork, InProcessTransport
    from btcap.transports.message import Address, Message, MessageRegistry
    from btcap.transports.security import DEFAULT_MAX_MESSAGE_BYTES, KeyPair, TeamKeys
    from btcap.transports.zeromq import ZmqTransport

#: Imported on first use (see btcap._lazy): a module that needs only the message types
#: (btcap.transports.message) loads neither asyncio nor pyzmq.
_EXPORTS = {
    "btcap.transports.base": ("BROADCAST", "Deliver", "Transport", "TransportStats"),
    "btcap.transports.codec": ("Codec", "CodecError", "Envelope", "Kind"),
    "btcap.transports.inprocess": ("InProcessNetwork", "InProcessTransport"),
    "btcap.transports.message": ("Address", "Message", "MessageRegistry"),
    "btcap.transports.security": ("DEFAULT_MAX_MESSAGE_BYTES", "KeyPair", "TeamKeys"),
    "btcap.transports.zeromq": ("ZmqTransport",),
}

if not TYPE_CHECKING:
    from btcap._lazy import lazy_exports

    __getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

__all__ = [
    "BROADCAST",
    "DEFAULT_MAX_MESSAGE_BYTES",
    "Address",
    "Codec",
    "CodecError",
    "Deliver",
    "Envelope",
    "InProcessNetwork",
    "InProcessTransport",
    "KeyPair",
    "Kind",
    "Message",
    "MessageRegistry",
    "TeamKeys",
    "Transport",
    "TransportStats",
    "ZmqTransport",
]
