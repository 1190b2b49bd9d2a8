"""The sans-IO codec: every registered message survives the wire; bad input is a CodecError."""

from __future__ import annotations

import math
from typing import Any

import msgspec
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from btcap.actors import Failure, runtime_messages
from btcap.transports import Address, Codec, CodecError, Envelope, Kind, Message, MessageRegistry

# -- message types of several shapes ------------------------------------------------------


class Point(msgspec.Struct):
    """A nested plain struct (a map on the wire)."""

    x: float
    y: float


class Pose(msgspec.Struct, array_like=True):
    """A nested array-like struct holding another struct."""

    position: Point
    heading: float


class Empty(Message):
    pass


class Scalars(Message):
    i: int
    f: float
    s: str
    b: bool
    raw: bytes


class Optionals(Message):
    name: str
    note: str | None = None
    level: int | None = None
    ratio: float | None = None


class Lists(Message):
    names: list[str]
    points: list[Point]
    matrix: list[list[float]]


class Nested(Message):
    pose: Pose
    tags: dict[str, int]
    groups: dict[str, list[str]]
    maybe: Pose | None = None


class Batch(Message):
    """Messages inside a message."""

    items: list[Scalars]
    first: Empty


class Renamed(Message, tag="custom.renamed"):
    """A message with an explicit string tag."""

    text: str


MESSAGE_TYPES: list[type[Message]] = [
    Empty,
    Scalars,
    Optionals,
    Lists,
    Nested,
    Batch,
    Renamed,
    Failure,
]

# -- strategies -----------------------------------------------------------------------------

#: MessagePack carries integers of at most 64 bits; wider ones are a CodecError (tested).
int64 = st.integers(min_value=-(2**63), max_value=2**63 - 1)

scalars = st.builds(Scalars, i=int64)
STRATEGIES: dict[type[Message], st.SearchStrategy[Any]] = {
    Empty: st.from_type(Empty),
    Scalars: scalars,
    Optionals: st.builds(
        Optionals,
        note=st.none() | st.text(),
        level=st.none() | int64,
        ratio=st.none() | st.floats(),
    ),
    Lists: st.from_type(Lists),
    Nested: st.builds(
        Nested,
        tags=st.dictionaries(st.text(), int64),
        maybe=st.none() | st.from_type(Pose),
    ),
    Batch: st.builds(Batch, items=st.lists(scalars, max_size=4)),
    Renamed: st.from_type(Renamed),
    Failure: st.from_type(Failure),
}
addresses = st.builds(Address, st.text(), st.text())
corrs = st.integers(min_value=0, max_value=2**64 - 1)


def envelopes(msgs: st.SearchStrategy[Any]) -> st.SearchStrategy[Envelope]:
    return st.builds(Envelope, st.sampled_from(Kind), addresses, addresses, msgs, corrs)


any_envelope = envelopes(st.one_of(st.none(), *STRATEGIES.values()))


def full_registry() -> MessageRegistry:
    registry = runtime_messages()
    registry.register(*MESSAGE_TYPES)
    return registry


def has_nan(value: Any) -> bool:
    """Whether a decoded-to-builtins value holds a NaN (which never equals itself)."""
    if isinstance(value, float):
        return math.isnan(value)
    if isinstance(value, dict):
        return any(has_nan(v) for v in value.values())
    if isinstance(value, list | tuple):
        return any(has_nan(v) for v in value)
    return False


def assert_round_trip(codec: Codec, env: Envelope) -> None:
    frame = codec.encode(env)
    back = codec.decode(frame)
    assert type(back) is Envelope
    assert type(back.msg) is type(env.msg)
    assert back.kind is env.kind
    assert (back.sender, back.recipient, back.corr) == (env.sender, env.recipient, env.corr)
    assert codec.encode(back) == frame
    if not has_nan(msgspec.to_builtins(env.msg)):
        assert back == env


# -- round trips ----------------------------------------------------------------------------


def test_every_test_message_type_has_a_strategy() -> None:
    assert set(STRATEGIES) == set(MESSAGE_TYPES)
    assert set(runtime_messages()) <= set(MESSAGE_TYPES)


@pytest.mark.parametrize("kind", list(Kind), ids=lambda k: k.name)
@pytest.mark.parametrize("msg_type", MESSAGE_TYPES, ids=lambda t: t.__name__)
def test_every_message_type_round_trips_in_every_kind(msg_type: type[Message], kind: Kind) -> None:
    codec = Codec(full_registry())

    @settings(max_examples=25)
    @given(msg=STRATEGIES[msg_type], sender=addresses, recipient=addresses, corr=corrs)
    def check(msg: Message, sender: Address, recipient: Address, corr: int) -> None:
        assert_round_trip(codec, Envelope(kind, sender, recipient, msg, corr))

    check()


@pytest.mark.parametrize("kind", list(Kind), ids=lambda k: k.name)
def test_an_empty_payload_round_trips(kind: Kind) -> None:
    codec = Codec(MessageRegistry())
    assert_round_trip(codec, Envelope(kind, Address("a", "b"), Address("*", "c/d"), None, 7))


def test_single_messages_round_trip() -> None:
    codec = Codec(full_registry())
    msg = Nested(Pose(Point(1.5, -2.0), 0.25), {"a": 1}, {"g": ["x", "y"]}, None)
    assert codec.decode_message(codec.encode_message(msg)) == msg
    with pytest.raises(CodecError, match="nil"):
        codec.decode_message(msgspec.msgpack.encode(None))


def test_the_decoder_follows_registrations_made_after_it_was_built() -> None:
    registry = MessageRegistry([Empty])
    codec = Codec(registry)
    sender = Address("a", "x")
    assert_round_trip(codec, Envelope(Kind.TELL, sender, sender, Empty()))
    late = Envelope(Kind.ASK, sender, sender, Renamed("late"), 3)
    frame = Codec(MessageRegistry([Renamed])).encode(late)
    with pytest.raises(CodecError):
        codec.decode(frame)
    registry.register(Renamed)
    assert codec.decode(frame) == late


# -- what cannot be encoded -----------------------------------------------------------------


def test_unregistered_message_types_are_not_encoded() -> None:
    codec = Codec(MessageRegistry([Empty]))
    with pytest.raises(CodecError, match="Renamed is not registered"):
        codec.encode(Envelope(Kind.TELL, Address("a", "b"), Address("c", "d"), Renamed("x")))


@pytest.mark.parametrize(
    "msg",
    [
        Scalars(i=2**64, f=0.0, s="", b=False, raw=b""),
        Scalars(i=-(2**63) - 1, f=0.0, s="", b=False, raw=b""),
        Renamed(text=object()),  # type: ignore[arg-type]
    ],
    ids=["int-too-big", "int-too-small", "unencodable-object"],
)
def test_values_the_wire_cannot_carry_are_codec_errors(msg: Message) -> None:
    codec = Codec(full_registry())
    with pytest.raises(CodecError, match="cannot be encoded"):
        codec.encode(Envelope(Kind.TELL, Address("a", "b"), Address("c", "d"), msg))


# -- malformed input ------------------------------------------------------------------------

CODEC = Codec(full_registry())


def decodes_or_codec_error(data: bytes) -> None:
    """Decoding either yields an envelope or raises CodecError, never anything else."""
    try:
        env = CODEC.decode(data)
    except CodecError:
        return
    assert type(env) is Envelope


@settings(max_examples=300)
@given(st.binary(max_size=256))
@example(b"")
@example(b"\xc1")  # a byte MessagePack never uses
@example(b"\x95" + b"\x91" * 5000)  # deeply nested arrays
@example(b"\x95\x00\x92\xa0\xa1\x80\x92\xa0\xa0\xc0\x00")  # invalid UTF-8 in a path
def test_random_bytes_never_raise_anything_but_codec_error(data: bytes) -> None:
    decodes_or_codec_error(data)


@settings(max_examples=60)
@given(any_envelope, st.data())
def test_every_truncated_frame_is_a_codec_error(env: Envelope, data: st.DataObject) -> None:
    frame = CODEC.encode(env)
    cut = data.draw(st.integers(min_value=0, max_value=len(frame) - 1), label="cut")
    with pytest.raises(CodecError):
        CODEC.decode(frame[:cut])


@settings(max_examples=100)
@given(any_envelope, st.data())
def test_corrupted_frames_never_raise_anything_but_codec_error(
    env: Envelope, data: st.DataObject
) -> None:
    frame = bytearray(CODEC.encode(env))
    at = data.draw(st.integers(min_value=0, max_value=len(frame) - 1), label="at")
    frame[at] = data.draw(st.integers(min_value=0, max_value=255), label="byte")
    decodes_or_codec_error(bytes(frame))


@given(any_envelope, st.binary(min_size=1, max_size=8))
@settings(max_examples=30)
def test_trailing_bytes_after_a_frame_are_a_codec_error(env: Envelope, extra: bytes) -> None:
    with pytest.raises(CodecError):
        CODEC.decode(CODEC.encode(env) + extra)


msgpack_values = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(min_value=-(2**63), max_value=2**64 - 1)
    | st.floats()
    | st.text(max_size=8)
    | st.binary(max_size=8),
    lambda inner: (
        st.lists(inner, max_size=6) | st.dictionaries(st.text(max_size=6), inner, max_size=4)
    ),
    max_leaves=20,
)


@settings(max_examples=150)
@given(msgpack_values)
def test_valid_msgpack_of_any_shape_decodes_or_is_a_codec_error(value: Any) -> None:
    decodes_or_codec_error(msgspec.msgpack.encode(value))


A = ["a", "b"]


@pytest.mark.parametrize(
    "value",
    [
        None,
        [],
        {"kind": 0},
        [0, A, A, None],  # too short
        [0, A, A, None, 0, 0],  # too long
        [9, A, A, None, 0],  # unknown kind
        ["tell", A, A, None, 0],
        [0, "a/b", A, None, 0],  # address as text
        [0, ["a"], A, None, 0],
        [0, A, A, None, "1"],  # correlation id as text
        [0, A, A, None, -1.5],
        [0, A, A, ["NoSuchMessage"], 0],  # an unregistered tag
        [0, A, A, ["Renamed"], 0],  # a registered tag with a field missing
        [0, A, A, ["Renamed", 5], 0],  # ... or of the wrong type
        [0, A, A, ["Renamed", "x", "extra"], 0],
        [0, A, A, {"type": "Renamed", "text": "x"}, 0],  # map form of an array-like struct
        [0, A, A, ["Scalars", "1", 0.0, "", False, b""], 0],  # a nested field mistyped
        [0, A, A, ["Batch", [["Empty"]], ["Empty"]], 0],  # a nested message of the wrong type
        [0, A, A, ["Nested", [[1.0, 2.0], 0.0], {}, {}, None], 0],  # a map struct as array
    ],
)
def test_wrong_shapes_are_codec_errors(value: Any) -> None:
    with pytest.raises(CodecError):
        CODEC.decode(msgspec.msgpack.encode(value))


def test_an_unregistered_tag_is_a_codec_error() -> None:
    frame = Codec(MessageRegistry([Renamed])).encode(
        Envelope(Kind.TELL, Address("a", "b"), Address("c", "d"), Renamed("x"))
    )
    with pytest.raises(CodecError, match=r"custom\.renamed"):
        Codec(MessageRegistry([Empty])).decode(frame)


def test_decode_message_rejects_garbage() -> None:
    for data in (b"", b"\xc1", msgspec.msgpack.encode(["Nope"]), b"\x91\x91"):
        with pytest.raises(CodecError):
            CODEC.decode_message(data)


# -- the registry ---------------------------------------------------------------------------


class Clash(Message, tag="custom.renamed"):
    text: str


class IntTagged(Message, tag=5):
    pass


def test_two_types_with_one_tag_are_rejected_naming_both() -> None:
    registry = MessageRegistry([Renamed])
    with pytest.raises(ValueError, match=r"'custom\.renamed'.*Clash.*Renamed"):
        registry.register(Clash)
    assert list(registry) == [Renamed]
    with pytest.raises(ValueError, match="already taken"):
        MessageRegistry([Renamed, Clash])


@pytest.mark.parametrize(
    "bad",
    [int, str, Message, Point, Renamed("x"), "Renamed", None],
    ids=["int", "str", "Message", "plain-struct", "instance", "name", "None"],
)
def test_registering_a_non_message_raises_type_error(bad: Any) -> None:
    registry = MessageRegistry()
    with pytest.raises(TypeError, match=r"not a subclass of transports\.Message"):
        registry.register(bad)
    assert len(registry) == 0


def test_non_string_tags_are_rejected() -> None:
    with pytest.raises(TypeError, match="string tags"):
        MessageRegistry([IntTagged])


def test_registry_membership_version_and_merge() -> None:
    registry = MessageRegistry([Empty])
    version = registry.version
    registry.register(Empty)  # registering again changes nothing
    assert registry.version == version
    assert len(registry) == 1
    other = MessageRegistry([Renamed, Empty])
    registry.merge(other)
    assert registry.version > version
    assert Renamed in registry
    assert Scalars not in registry
    assert set(registry) == {Empty, Renamed}
