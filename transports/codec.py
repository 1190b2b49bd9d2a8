"""Sans-IO MessagePack codec for envelopes: bytes in, typed envelopes out, no sockets."""

from __future__ import annotations

import enum
from typing import Any, Union

import msgspec

from btcap._enum import FastEnumType
from btcap.errors import BtcapError
from btcap.transports.message import Address, Message, MessageRegistry

__all__ = ["Codec", "CodecError", "Envelope", "Header", "Kind"]


class Kind(enum.IntEnum, metaclass=FastEnumType):
    """What an envelope is for; asks and their replies share a correlation id."""

    TELL = 0
    ASK = 1
    REPLY = 2
    FAIL = 3


class Envelope(msgspec.Struct, array_like=True, gc=False):
    """A message in transit between actor systems."""

    kind: Kind
    sender: Address
    recipient: Address
    msg: Message | None
    corr: int = 0


Header = tuple[Kind, Address, Address, msgspec.Raw, int]
"""An envelope with its message still encoded: who sent it to whom checked first."""


class CodecError(BtcapError, ValueError):
    """A frame could not be decoded into a registered message."""


class Codec:
    """Encodes and decodes envelopes whose payload is any registered message.

    The encoder and decoder are built once and reused; the decoder is rebuilt only when
    the registry has grown since it was made.
    """

    __slots__ = (
        "_body",
        "_by_tag",
        "_decoder",
        "_encoder",
        "_header",
        "_registry",
        "_types",
        "_version",
    )

    def __init__(self, registry: MessageRegistry) -> None:
        self._registry = registry
        # The registry's own set, which grows in place: ``in`` on it, not a method call.
        self._types = registry._types
        self._encoder = msgspec.msgpack.Encoder()
        self._version = -1
        self._decoder: msgspec.msgpack.Decoder[Any] = msgspec.msgpack.Decoder()
        self._header: msgspec.msgpack.Decoder[Header] = msgspec.msgpack.Decoder(Header)
        self._body: msgspec.msgpack.Decoder[Any] = msgspec.msgpack.Decoder()
        self._by_tag: dict[bytes, type[Message]] = {}

    @property
    def registry(self) -> MessageRegistry:
        return self._registry

    def _refresh(self) -> msgspec.msgpack.Decoder[Any]:
        if self._version != self._registry.version:
            types = tuple(self._registry)
            if types:
                payload: Any = Union[(*types, None)]
            else:
                payload = None
            # A tuple decodes the envelope's array form straight into typed fields.
            self._decoder = msgspec.msgpack.Decoder(tuple[Kind, Address, Address, payload, int])
            self._body = msgspec.msgpack.Decoder(payload)
            self._by_tag = {t.__struct_config__.tag.encode(): t for t in types}  # type: ignore[union-attr]
            self._version = self._registry.version
        return self._decoder

    def encode(self, env: Envelope) -> bytes:
        msg = env.msg
        if msg is not None and type(msg) not in self._types:
            raise CodecError(f"message type {type(msg).__qualname__} is not registered")
        try:
            return self._encoder.encode(env)
        except (msgspec.EncodeError, TypeError, OverflowError) as exc:  # e.g. an int > 64 bit
            raise CodecError(f"{type(msg).__qualname__} cannot be encoded: {exc}") from None
        except RecursionError:
            raise CodecError(f"{type(msg).__qualname__} is nested too deeply") from None

    def decode(self, data: bytes | memoryview) -> Envelope:
        decoder = self._decoder
        if self._version != self._registry._version:
            decoder = self._refresh()
        try:
            kind, sender, recipient, msg, corr = decoder.decode(data)
        except (msgspec.DecodeError, UnicodeDecodeError) as exc:  # bad UTF-8 is not wrapped
            raise CodecError(str(exc)) from None
        except RecursionError:
            # msgspec stops at the interpreter's recursion limit; without this a hostile
            # frame would reach the receiver as an unexpected error, traceback and all.
            raise CodecError("nested too deeply") from None
        return Envelope(kind, sender, recipient, msg, corr)

    def decode_header(self, data: bytes | memoryview) -> Header:
        """An envelope whose message is left encoded (see :meth:`decode_body`): the
        receiver checks its sender, the message's type (:meth:`message_type`) and size
        before paying for the message itself."""
        try:
            return self._header.decode(data)
        except (msgspec.DecodeError, UnicodeDecodeError) as exc:
            raise CodecError(str(exc)) from None
        except RecursionError:
            raise CodecError("nested too deeply") from None

    def message_type(self, tag: bytes | None) -> type[Message] | None:
        """The registered type of a message tag (:func:`~btcap.transports.bounds.message_tag`)."""
        if self._version != self._registry._version:
            self._refresh()
        return self._by_tag.get(tag) if tag is not None else None

    def decode_body(self, raw: msgspec.Raw) -> Message | None:
        """The message of a :meth:`decode_header`, decoded now."""
        decoder = self._body
        if self._version != self._registry._version:
            self._refresh()
            decoder = self._body
        try:
            msg: Message | None = decoder.decode(raw)
        except (msgspec.DecodeError, UnicodeDecodeError) as exc:
            raise CodecError(str(exc)) from None
        except RecursionError:
            raise CodecError("nested too deeply") from None
        return msg

    def encode_message(self, msg: Message) -> bytes:
        """One message on its own, for files and tests."""
        return self._encoder.encode(msg)

    def decode_message(self, data: bytes) -> Message:
        env = self.decode(
            self._encoder.encode((Kind.TELL, _NOWHERE, _NOWHERE, msgspec.Raw(data), 0))
        )
        if env.msg is None:
            raise CodecError("expected a message, got nil")
        return env.msg


_NOWHERE = Address("-", "-")
