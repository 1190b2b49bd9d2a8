"""The monitor bench runs: every shape ticked with and without a monitor, a page reading."""

from __future__ import annotations

from pathlib import Path

import pytest

from btcap.bench import common
from btcap.bench.speed import monitor


def test_the_quick_monitor_bench_measures_every_shape(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(common, "RESULTS", tmp_path)
    data = monitor.run(quick=True)
    assert set(data["cpu_ratio"]) == set(monitor.SHAPES)
    assert all(ratio > 0 for ratio in data["cpu_ratio"].values())
    assert all(sent > 0 for sent in data["batches"].values())  # the page was sent each shape
    assert (tmp_path / "monitor.json").exists()
