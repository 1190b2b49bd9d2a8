"""A ``--fast`` run is reproducible down to its recording: the same scenario and seed give
byte-identical ``result.json`` and ``monitor.jsonl``, in one process or two with different
hash randomisation (the monitor batches on the virtual clock; lives are numbered by the
run, so ids are the same)."""

from __future__ import annotations

import asyncio
import os
import sys
from pathlib import Path

import anyio
import pytest

SMALL = Path(__file__).parents[1] / "data" / "small.yaml"
FILES = ("result.json", "monitor.jsonl")


def written(out: Path) -> dict[str, bytes]:
    return {name: (out / name).read_bytes() for name in FILES}


@pytest.mark.slow
def test_two_fast_runs_record_the_same_bytes(small_fast_twice: tuple[Path, Path]) -> None:
    first, second = (written(out) for out in small_fast_twice)
    assert first["monitor.jsonl"].count(b"\n") > 50  # tree states, runs and auctions
    assert b'"k":"states"' in first["monitor.jsonl"]
    assert first == second


@pytest.mark.slow
async def test_the_recording_does_not_depend_on_hash_randomisation(
    tmp_path: Path, small_fast_twice: tuple[Path, Path]
) -> None:
    """A process with another hash seed than this one's (random unless PYTHONHASHSEED
    is set) records what this process recorded (conftest.py's runs)."""
    mine = os.environ.get("PYTHONHASHSEED")

    async def run(hash_seed: str) -> dict[str, bytes]:
        assert hash_seed != mine
        out = tmp_path / hash_seed
        proc = await asyncio.create_subprocess_exec(
            sys.executable,
            "-m",
            "btcap",
            "run",
            str(SMALL),
            "--fast",
            "--quiet",
            "--out",
            str(out),
            stdout=asyncio.subprocess.DEVNULL,
            stderr=asyncio.subprocess.DEVNULL,
            env={**os.environ, "PYTHONHASHSEED": hash_seed},
        )
        assert await proc.wait() == 0
        return written(out)

    with anyio.fail_after(120):
        other = await run("2" if mine == "1" else "1")
    assert other == written(small_fast_twice[0])
