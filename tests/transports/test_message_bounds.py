"""transports.bounds: a message's containers and depth checked on its bytes (sans-IO),
its tag and a big frame's envelope read without decoding them."""

from __future__ import annotations

import random
from typing import Any

import msgspec
import pytest

from btcap.transports import Address, Envelope, Kind, Message, MessageRegistry
from btcap.transports.bounds import (
    MAX_CONTAINERS,
    MAX_DEPTH,
    check_nesting,
    message_tag,
    split_envelope,
)
from btcap.transports.codec import Codec

encode = msgspec.msgpack.encode


class Free(Message):
    value: Any


def nest(depth: int) -> Any:
    value: Any = 0
    for _ in range(depth):
        value = [value]
    return value


def shape(value: Any) -> tuple[int, int]:
    """(containers, depth) of a decoded value, counted the plain way."""
    if isinstance(value, list | dict):
        items = list(value.values()) + list(value) if isinstance(value, dict) else value
        inner = [shape(v) for v in items]
        return 1 + sum(c for c, _ in inner), 1 + max((d for _, d in inner), default=0)
    return 0, 0


def test_depth_is_bounded_at_max_depth() -> None:
    assert check_nesting(encode([nest(MAX_DEPTH - 1), "x" * 100])) is None
    assert (
        check_nesting(encode([nest(MAX_DEPTH), "x" * 100])) == f"nested more than {MAX_DEPTH} deep"
    )


def test_containers_are_bounded_at_max_containers() -> None:
    assert check_nesting(encode([[] for _ in range(MAX_CONTAINERS - 1)])) is None
    why = check_nesting(encode([[] for _ in range(MAX_CONTAINERS)]))
    assert why == f"more than {MAX_CONTAINERS} arrays and maps"


def test_the_attack_shape_is_refused_and_big_plain_data_is_not() -> None:
    assert check_nesting(encode([nest(100) for _ in range(2_000)])) is not None
    rng = random.Random(7)
    plain = [
        [rng.random() for _ in range(400_000)],  # floats packed with container-like bytes
        rng.randbytes(1_000_000),
        "é" * 500_000,  # UTF-8: every other byte looks like a fixmap
        list(range(200_000)),
        [[rng.random(), rng.random()] for _ in range(20_000)],  # waypoints
        {f"k{i}": {"x": i, "y": [i, -i]} for i in range(5_000)},
    ]
    for value in plain:
        assert check_nesting(encode(value)) is None


@pytest.mark.parametrize("seed", range(6))
def test_the_verdict_matches_the_value_counted_the_plain_way(seed: int) -> None:
    rng = random.Random(seed)
    budget = [0]

    def value(depth: int) -> Any:
        budget[0] -= 1
        pick = rng.random()
        if depth > 100 or budget[0] < 0 or pick < 0.25:
            return rng.choice([1, -5, 300, 1.5, "s", "é" * 40, None, True, b"\x90\x91", 2**40])
        width = rng.choice([0, 1, 1, 1, 2, 3, 40])
        if pick < 0.65:
            return [value(depth + 1) for _ in range(width)]
        return {f"k{i}": value(depth + 1) for i in range(width)}

    verdicts = set()
    for _ in range(12):
        budget[0] = rng.choice([50, 2_000, 40_000])
        v = [value(0) for _ in range(rng.choice([1, 5, 50]))]
        containers, depth = shape(v)
        expected = containers <= MAX_CONTAINERS and depth <= MAX_DEPTH
        assert (check_nesting(encode(v)) is None) == expected, (containers, depth)
        verdicts.add(expected)
    assert verdicts == {True, False}  # both sides of the bounds were tried


def test_truncated_or_foreign_bytes_are_left_to_the_decoder() -> None:
    data = encode([nest(10) for _ in range(30)])
    assert check_nesting(data[: len(data) // 2]) is None
    assert check_nesting(b"\xc1" * 200) is None


def test_a_message_tag_is_read_without_decoding() -> None:
    codec = Codec(MessageRegistry([Free]))
    assert message_tag(codec.encode_message(Free([1, 2]))) == b"Free"
    assert message_tag(encode(None)) is None
    assert message_tag(b"") is None


@pytest.mark.parametrize("name", ["r1", "x" * 31, "y" * 32, "z" * 300])
def test_a_big_frame_envelope_is_read_as_the_codec_reads_it(name: str) -> None:
    codec = Codec(MessageRegistry([Free]))
    for kind in Kind:
        env = Envelope(kind, Address(name, "a/b"), Address("to", "p" * 40), Free("v" * 1000), 7)
        data = memoryview(codec.encode(env))
        got = split_envelope(data)
        assert got is not None
        k, sender, to, start = got
        header = codec.decode_header(data)
        assert (k, sender, to) == (kind, name, "to")
        assert bytes(data[start : start + len(header[3])]) == bytes(header[3])
    assert split_envelope(memoryview(encode([1, 2, 3, 4, 5, 6]))) is None
