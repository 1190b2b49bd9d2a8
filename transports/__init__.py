"""Moving typed envelopes between actor systems: codec, in-process and ZeroMQ transports."""

from transports.base import BROADCAST, Deliver, Transport, TransportStats
from transports.codec import Codec, CodecError, Envelope, Kind
from transports.inprocess import InProcessNetwork, InProcessTransport
from transports.message import Address, Message, MessageRegistry
from transports.zeromq import ZmqTransport

__all__ = [
    "BROADCAST",
    "Address",
    "Codec",
    "CodecError",
    "Deliver",
    "Envelope",
    "InProcessNetwork",
    "InProcessTransport",
    "Kind",
    "Message",
    "MessageRegistry",
    "Transport",
    "TransportStats",
    "ZmqTransport",
]
