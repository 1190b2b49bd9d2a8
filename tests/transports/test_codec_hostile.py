"""Hostile frames cost the codec little: nesting past the interpreter's limit is a
CodecError like any other bad frame, in either direction, and fails fast."""

from __future__ import annotations

from typing import Any

import msgspec
import pytest

from btcap.transports import Address, Codec, CodecError, Envelope, Kind, Message, MessageRegistry


class Loose(Message):
    """A payload that holds anything, like a capability's port values."""

    value: Any


CODEC = Codec(MessageRegistry([Loose]))
A = Address("a", "b")


def nested_frame(depth: int) -> bytes:
    """A valid envelope whose Loose payload holds ``depth`` nested one-element arrays."""
    head = msgspec.msgpack.encode([0, A, A, msgspec.Raw(b"\x92\xa5Loose"), 0])
    # Splice the nested value into the payload array: [tag, value].
    payload = b"\x92\xa5Loose" + b"\x91" * depth + b"\xc0"
    return head.replace(b"\x92\xa5Loose", payload)


def test_a_moderately_nested_value_decodes() -> None:
    env = CODEC.decode(nested_frame(50))
    assert isinstance(env.msg, Loose)


@pytest.mark.parametrize("depth", [5_000, 1_000_000])
def test_nesting_past_the_limit_is_a_codec_error_without_a_traceback(depth: int) -> None:
    # A RecursionError's traceback logged per hostile frame cost ~100 ms each: the codec
    # error chains nothing that a receiver would format. (No timing here: load decides it.)
    with pytest.raises(CodecError, match="nested too deeply") as refused:
        CODEC.decode(nested_frame(depth))
    assert refused.value.__cause__ is None
    assert refused.value.__suppress_context__


def test_encoding_a_value_nested_too_deeply_is_a_codec_error() -> None:
    value: list[Any] = []
    for _ in range(5_000):
        value = [value]
    with pytest.raises(CodecError, match="Loose is nested too deeply"):
        CODEC.encode(Envelope(Kind.TELL, A, A, Loose(value)))
