"""Every message the simulation speaks survives the wire codec (rule 2 of the design)."""

from __future__ import annotations

import math
import types
import typing
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from btcap.sim.running.hosts import registry
from btcap.sim.world.messages import SIM_MESSAGES
from btcap.transports import Address, Codec, Envelope, Kind, Message

CODEC = Codec(registry())
INT64 = st.integers(-(2**63), 2**63 - 1)


def _strategy(hint: Any) -> st.SearchStrategy[Any]:
    """Values of a field type, with ints bounded to what MessagePack carries."""
    origin = typing.get_origin(hint)
    args = typing.get_args(hint)
    if hint is int:
        return INT64
    if origin is tuple and len(args) == 2 and args[1] is Ellipsis:  # tuple[int, ...]
        return st.lists(_strategy(args[0]), max_size=5).map(tuple)
    if origin is tuple:
        return st.tuples(*(_strategy(a) for a in args))
    if origin is list:
        return st.lists(_strategy(args[0]), max_size=5)
    if origin in (typing.Union, types.UnionType):
        return st.one_of(*(_strategy(a) for a in args))
    if hint is type(None):
        return st.none()
    return st.from_type(hint)


def _messages(kind: type[Message]) -> st.SearchStrategy[Message]:
    hints = typing.get_type_hints(kind)
    return st.builds(kind, **{f: _strategy(hints[f]) for f in kind.__struct_fields__})


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a):
        return math.isnan(b)
    return bool(a == b)


@pytest.mark.parametrize("kind", SIM_MESSAGES, ids=lambda t: t.__name__)
@settings(max_examples=40, deadline=None)
@given(data=st.data())
def test_sim_messages_round_trip(kind: type[Message], data: st.DataObject) -> None:
    msg = data.draw(_messages(kind))
    env = Envelope(Kind.TELL, Address("a", "x"), Address("b", "y"), msg)
    back = CODEC.decode(CODEC.encode(env))
    assert type(back.msg) is kind
    for field in kind.__struct_fields__:
        assert _same(getattr(back.msg, field), getattr(msg, field)), field


def test_every_sim_message_is_registered() -> None:
    reg = registry()
    assert all(t in reg for t in SIM_MESSAGES)
