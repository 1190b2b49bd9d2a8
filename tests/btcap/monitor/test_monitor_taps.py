"""A tap reads its tree's states only in batches after a node changed state: a ``--fast``
run's batches (one per simulator step) mostly follow ticks that changed nothing."""

from __future__ import annotations

import anyio

from btcap import Leaf, Monitor, ReactiveSequence, State, Tree
from btcap.actors import ManualClock


class _Counted(Leaf):
    """A leaf that runs until told, counting the reads of its state while ``watching``."""

    watching = False
    reads = 0
    result = State.RUNNING

    @property  # type: ignore[override]
    def state(self) -> State:
        if _Counted.watching:
            _Counted.reads += 1
        return self._state

    @state.setter
    def state(self, value: State) -> None:
        self._state = value

    def on_tick(self) -> State:
        return self.result


async def test_a_batch_after_ticks_that_changed_nothing_reads_no_node() -> None:
    leaf = _Counted("a")
    tree = Tree(ReactiveSequence("root", children=[leaf]), clock=ManualClock())
    tree.setup()
    with anyio.fail_after(10):
        async with Monitor(port=None) as monitor:
            monitor.add_tree(tree, robot="r1")
            tree.tick()
            monitor.flush()  # root and a running
            for _ in range(10):
                tree.tick()  # nothing changes
            _Counted.watching = True
            try:
                assert monitor.flush() == []
                assert _Counted.reads == 0
                leaf.result = State.SUCCEEDED
                tree.tick()
                batch = monitor.flush()
                tree.untick()  # a change outside a tick is sent too
                after = monitor.flush()
            finally:
                _Counted.watching = False
                await tree.shutdown()
    assert [ev["states"] for ev in batch] == [{"root/a": "succeeded", "root": "succeeded"}]
    assert [ev["states"] for ev in after] == [{"root": "idle"}]
