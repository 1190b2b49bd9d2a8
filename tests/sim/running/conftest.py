"""Runs that several test modules of this folder judge: made once per session."""

from __future__ import annotations

from pathlib import Path

import pytest

import btcap.cli
from btcap.cli import main

SMALL = Path(__file__).parents[1] / "data" / "small.yaml"


@pytest.fixture(scope="session")
def small_fast_twice(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The output folders of ``btcap run small.yaml --fast`` run twice in this process,
    one after the other (each writes result.json, timeline.png and monitor.jsonl):
    test_cli_run.py compares their results, test_fast_recording.py their recordings
    and, against a process with another hash seed, test_fast_recording.py again."""
    outs = (
        tmp_path_factory.mktemp("small-fast") / "a",
        tmp_path_factory.mktemp("small-fast") / "b",
    )
    with pytest.MonkeyPatch.context() as mp:
        # main() would configure logging for the process, onto a stderr pytest closes.
        mp.setattr(btcap.cli, "configure_logging", lambda level, json=False: None)
        for out in outs:
            assert main(["run", str(SMALL), "--fast", "--quiet", "--out", str(out)]) == 0
    return outs
