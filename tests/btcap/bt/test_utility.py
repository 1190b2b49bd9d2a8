"""Utility bounds: how composites aggregate the cost of their children, and who can run."""

from __future__ import annotations

import math

import msgspec
import pytest

from btcap import (
    AlwaysSuccess,
    Fallback,
    IfThenElse,
    Inverter,
    Leaf,
    Parallel,
    ReactiveFallback,
    ReactiveSequence,
    Sequence,
    State,
    Switch,
    Tree,
    Utility,
)
from btcap.bt.utility import CANNOT, fallback_utility, parallel_utility, sequence_utility

A = Utility(True, 1.0, 2.0, 0.5, 1.0)
B = Utility(True, 3.0, 4.0, 1.0, 2.0)


class Costed(Leaf):
    """A leaf with a fixed utility estimate."""

    def __init__(self, name: str, utility: Utility) -> None:
        super().__init__(name)
        self._utility = utility

    def on_tick(self) -> State:
        return State.SUCCEEDED

    def utility(self) -> Utility:
        return self._utility


def test_default_utility_is_free_and_executable() -> None:
    u = AlwaysSuccess().utility()
    assert u == Utility(True, 0.0, 0.0, 0.0, 0.0)
    assert u.expected_cost == 0.0


def test_addition_and_expected_cost() -> None:
    assert Utility(True, 4.0, 6.0, 1.5, 3.0) == A + B
    assert (A + CANNOT).can_execute is False
    assert B.expected_cost == 3.5
    assert CANNOT.expected_cost == math.inf
    assert Utility(False, 1.0, 1.0).expected_cost == math.inf


def test_utility_round_trips_msgpack() -> None:
    data = msgspec.msgpack.encode(A)
    assert msgspec.msgpack.decode(data, type=Utility) == A


def test_sequence_sums_success_and_bounds_failure() -> None:
    assert sequence_utility([A, B]) == Utility(True, 4.0, 6.0, 0.5, 8.0)
    assert sequence_utility([]) == Utility()
    assert sequence_utility([A]) == Utility(True, 1.0, 2.0, 0.5, 3.0)


def test_sequence_failure_lower_bound_is_the_cheapest_way_to_fail() -> None:
    cheap_late = Utility(True, 1.0, 1.0, 0.1, 0.1)
    dear_early = Utility(True, 1.0, 1.0, 5.0, 5.0)
    # Failing early costs 5; succeeding at the first (1) then failing the second (0.1) costs 1.1.
    assert sequence_utility([dear_early, cheap_late]).failure_lower == pytest.approx(1.1)


def test_fallback_takes_the_cheapest_path_to_success() -> None:
    assert fallback_utility([A, B]) == Utility(True, 1.0, 5.0, 1.5, 3.0)
    dear = Utility(True, 10.0, 10.0, 1.0, 1.0)
    cheap = Utility(True, 2.0, 2.0, 1.0, 1.0)
    # Fail the dear child (1) then succeed with the cheap one (2): 3 beats 10.
    u = fallback_utility([dear, cheap])
    assert u.success_lower == 3.0
    assert u.success_upper == 10.0


def test_parallel_adds() -> None:
    assert parallel_utility([A, B, A]) == A + B + A
    assert parallel_utility([]) == Utility()


def test_composites_aggregate_their_children() -> None:
    a, b = Costed("a", A), Costed("b", B)
    assert ReactiveSequence("s", children=[a, b]).utility() == sequence_utility([A, B])
    a, b = Costed("a", A), Costed("b", B)
    assert Sequence("s", children=[a, b]).utility() == sequence_utility([A, B])
    a, b = Costed("a", A), Costed("b", B)
    assert ReactiveFallback("f", children=[a, b]).utility() == fallback_utility([A, B])
    a, b = Costed("a", A), Costed("b", B)
    assert Fallback("f", children=[a, b]).utility() == fallback_utility([A, B])
    a, b = Costed("a", A), Costed("b", B)
    assert Parallel("p", children=[a, b]).utility() == A + B
    a, b = Costed("a", A), Costed("b", B)
    assert Switch("sw", children=[a, b], cases=[1, 2]).utility() == fallback_utility([A, B])


def test_if_then_else_is_condition_and_then_or_else() -> None:
    c, t, e = Costed("c", A), Costed("t", B), Costed("e", A)
    ite = IfThenElse("ite", children=[c, t, e])
    assert ite.utility() == fallback_utility([sequence_utility([A, B]), A])


def test_decorators_and_trees_pass_utility_through() -> None:
    inv = Inverter("inv", children=[Costed("a", A)])
    assert inv.utility() == A
    assert Inverter("empty").utility() == Utility()
    tree = Tree(ReactiveSequence("root", children=[Costed("a", A), Costed("b", B)]))
    assert tree.utility() == sequence_utility([A, B])


def test_a_leaf_that_cannot_execute_makes_a_sequence_unable() -> None:
    tree = Tree(ReactiveSequence("root", children=[Costed("ok", A), Costed("no", CANNOT)]))
    u = tree.utility()
    assert u.can_execute is False
    assert u.expected_cost == math.inf


def test_a_fallback_stays_able_if_another_child_can() -> None:
    fb = ReactiveFallback("fb", children=[Costed("no", CANNOT), Costed("ok", B)])
    u = fb.utility()
    assert u.can_execute is True
    assert u == fallback_utility([B])  # the unable child is no path at all
    nested = ReactiveSequence("root", children=[Costed("a", A), fb])
    assert nested.utility().can_execute is True
    assert nested.utility() == sequence_utility([A, B])


def test_a_fallback_of_unable_children_is_unable() -> None:
    fb = ReactiveFallback(
        "fb", children=[Costed("x", CANNOT), Costed("y", Utility(can_execute=False))]
    )
    assert fb.utility() == CANNOT
    assert ReactiveSequence("s", children=[fb]).utility().can_execute is False
    assert (
        Parallel("p", children=[Costed("ok", A), Costed("no", CANNOT)]).utility().can_execute
        is False
    )
