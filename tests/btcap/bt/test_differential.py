"""btcap against py_trees 2.x on random trees, tick by tick (see ``difftrees``).

Each tick compares the root's result, the leaves ticked in order and the leaves halted;
btcap's halting invariant is checked after every tick too. Deliberate differences are
modelled on the py_trees side (``difftrees``' docstring lists them); any other difference
fails. The default run draws 300 trees; ``BTCAP_DIFF_TREES=5000`` (say) draws more.
Trees come from hypothesis with a fixed seed, so a failure is reproducible and shrunk.
"""

from __future__ import annotations

import os

import py_trees
import pytest
from difftrees import (
    COMPOSITES,
    DECORATORS,
    STATE_OF,
    Log,
    Spec,
    TickClock,
    build_btcap,
    build_py_trees,
    specs,
)
from hypothesis import example, given, settings

from btcap import State, Tree
from btcap.bt.invariants import tick_checked

S, F, R = State.SUCCEEDED, State.FAILED, State.RUNNING
TREES = int(os.environ.get("BTCAP_DIFF_TREES", "300"))
TICKS = 12


def leaf(name: str, *script: State) -> Spec:
    return Spec("leaf", name, script=script)


# The reported defects, always run: a running child under RunningIsSuccess left running;
# a Parallel whose success became impossible looping; success winning a tie.
ABANDONED = Spec("rfb", "r", (leaf("a", F), Spec("run_s", "d", (leaf("b", R),))))
IMPOSSIBLE = Spec("par", "r", (leaf("a", S), leaf("b", F), leaf("c", F)), need=2, fail=3)
TIE = Spec("par", "r", (leaf("a", S), leaf("b", F)), need=1, fail=1)


@pytest.mark.timeout(max(60, TREES // 25))  # a big opt-in run needs more than the default
@settings(max_examples=TREES, derandomize=True, database=None)
@example(ABANDONED)
@example(IMPOSSIBLE)
@example(TIE)
@given(specs())
def test_btcap_ticks_as_py_trees_where_not_documented_otherwise(spec: Spec) -> None:
    clock = TickClock()
    ours, theirs = Log(), Log()
    # debug=False: scripted leaves make restart loops on purpose (tests/btcap/bt/test_debug.py)
    tree = Tree(build_btcap(spec, ours, clock), clock=clock, debug=False)
    root = build_py_trees(spec, theirs, clock)
    for t in range(TICKS):
        clock.t = t
        for log in (ours, theirs):
            log.ticked.clear()
            log.halted.clear()
        got = tick_checked(tree)
        root.tick_once()
        want = STATE_OF[root.status]
        assert (got, ours.ticked, sorted(ours.halted)) == (
            want,
            theirs.ticked,
            sorted(theirs.halted),
        ), f"tick {t}: (root, ticked, halted) differ, btcap first"


def test_the_generator_covers_every_kind() -> None:
    seen: set[str] = set()

    @settings(max_examples=200, derandomize=True, database=None)
    @given(specs())
    def collect(spec: Spec) -> None:
        seen.update(s.kind for s in spec.walk())

    collect()
    assert seen == {*COMPOSITES, *DECORATORS, "leaf"}


def test_py_trees_is_2x() -> None:
    assert py_trees.version.__version__.startswith("2.")
