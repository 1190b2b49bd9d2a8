"""Giving the heap back after a burst: one trim per burst, once it is over, off the loop."""

from __future__ import annotations

import asyncio
import sys

import anyio
import pytest

from btcap.actors.heap import HeapTrim, malloc_trim

glibc = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's malloc_trim")


@glibc
def test_malloc_trim_is_found_on_linux() -> None:
    assert malloc_trim()


@glibc
async def test_a_burst_of_signs_is_one_trim_once_it_is_over() -> None:
    trim = HeapTrim(quiet_s=0.01, every_s=60.0)
    with anyio.fail_after(5):
        for _ in range(5):  # the burst goes on: the trim waits for its end
            trim.burst()
            await asyncio.sleep(0)
        assert trim.trims == 0
        while trim.trims == 0:  # noqa: ASYNC110 - a counter, no event to wait on
            await asyncio.sleep(0.005)
        trim.burst()  # within every_s of the last: put off, not run
        await asyncio.sleep(0.05)
        assert trim.trims == 1
        trim.cancel()
