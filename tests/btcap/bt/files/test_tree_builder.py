"""A tree file read once and built for every run (a capability implementation's): each
build is afresh, so what one run does to a list or mapping it was given from the file
is no trace in the next (nor in a spare built meanwhile in a worker thread)."""

from __future__ import annotations

import textwrap
from pathlib import Path

from btcap.bt.files.load import tree_builder

TREE = """\
btcap: 1
root:
  type: Sequence
  children:
    - {type: Constant, name: c, options: {value: {goals: [[1, 2], [3, 4]]}}}
    - {type: Compare, name: cmp, inputs: {a: [1, 2], b: {x: [5]}}}
"""


def test_each_build_owns_the_files_lists_and_mappings(tmp_path: Path) -> None:
    path = tmp_path / "impl.yaml"
    path.write_text(textwrap.dedent(TREE))
    build = tree_builder(path)
    first, second = build(), build()
    one = {n.name: n for n in first.nodes()}
    two = {n.name: n for n in second.nodes()}
    one["c"].options["value"]["goals"].pop()  # a run that uses its goals up
    one["cmp"].inputs["a"].append(3)
    one["cmp"].inputs["b"]["x"].clear()
    assert two["c"].options["value"] == {"goals": [[1, 2], [3, 4]]}
    assert two["cmp"].inputs["a"] == [1, 2]
    assert two["cmp"].inputs["b"] == {"x": [5]}
    third = {n.name: n for n in build().nodes()}
    assert third["c"].options["value"] == {"goals": [[1, 2], [3, 4]]}
    assert third["cmp"].inputs["a"] == [1, 2]
