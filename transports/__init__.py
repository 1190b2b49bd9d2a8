"""Moving typed envelopes between actor systems: codec, in-process and ZeroMQ transports."""

from btcap.transports.base import BROADCAST, Deliver, Transport, TransportStats
from btcap.transports.codec import Codec, CodecError, Envelope, Kind
from btcap.transports.inprocess import InProcessNetwork, InProcessTransport
from btcap.transports.message import Address, Message, MessageRegistry
from btcap.transports.security import DEFAULT_MAX_MESSAGE_BYTES, KeyPair, TeamKeys
from btcap.transports.zeromq import ZmqTransport

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
