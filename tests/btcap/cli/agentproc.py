"""``btcap agent`` in its own process, for the CLI tests: started, waited for until it
listens, stopped by a signal with what it said on stderr, and always killed and reaped."""

from __future__ import annotations

import contextlib
import signal
import subprocess
import sys
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from pathlib import Path

import anyio
import anyio.abc


def btcap(*args: str) -> list[str]:
    """The ``btcap`` command line, run by this interpreter."""
    return [sys.executable, "-m", "btcap", *args]


@asynccontextmanager
async def running_agent(
    config: Path, *flags: str, stderr: int = subprocess.DEVNULL
) -> AsyncIterator[anyio.abc.Process]:
    """``btcap agent CONFIG FLAGS`` once it says it listens; killed on exit if still up."""
    proc = await anyio.open_process(
        btcap("agent", str(config), *flags), stdout=subprocess.PIPE, stderr=stderr
    )
    try:
        assert proc.stdout is not None
        said = b""
        while b"listening" not in said:
            chunk = await proc.stdout.receive()
            said += chunk
        yield proc
    finally:
        with anyio.CancelScope(shield=True):
            if proc.returncode is None:
                proc.kill()
            await proc.aclose()


async def stop(proc: anyio.abc.Process, sig: signal.Signals) -> tuple[int, str]:
    """Send ``sig``; the exit code and everything the process wrote on stderr."""
    assert proc.stderr is not None
    proc.send_signal(sig)
    code = await proc.wait()
    err = b""
    with contextlib.suppress(anyio.EndOfStream):
        while True:
            err += await proc.stderr.receive()
    return code, err.decode()
