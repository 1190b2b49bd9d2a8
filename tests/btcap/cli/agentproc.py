"""``btcap agent`` in its own process, for the CLI tests: on a free port, started, waited
for until it listens, stopped by a signal with what it said on stderr, and always killed
and reaped."""

from __future__ import annotations

import contextlib
import random
import signal
import socket
import subprocess
import sys
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from pathlib import Path

import anyio
import anyio.abc


def free_port(taken: set[int]) -> int:
    """A free loopback port below Linux's ephemeral range, not in ``taken`` (then added):
    robots redial a port between runs, and a dial to a free ephemeral port can connect
    to itself."""
    rng = random.Random()
    while True:
        port = rng.randrange(20000, 32000)
        if port in taken:
            continue
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
            try:
                s.bind(("127.0.0.1", port))
            except OSError:
                continue
        taken.add(port)
        return port


def btcap(*args: str) -> list[str]:
    """The ``btcap`` command line, run by this interpreter."""
    return [sys.executable, "-m", "btcap", *args]


@asynccontextmanager
async def running_agent(
    config: Path, *flags: str, stderr: int = subprocess.DEVNULL
) -> AsyncIterator[anyio.abc.Process]:
    """``btcap agent CONFIG FLAGS`` once it says it listens; killed on exit if still up."""
    async with listening_agent(config, *flags, stderr=stderr) as (proc, _):
        yield proc


@asynccontextmanager
async def listening_agent(
    config: Path, *flags: str, stderr: int = subprocess.DEVNULL, log_level: str = "warning"
) -> AsyncIterator[tuple[anyio.abc.Process, str]]:
    """:func:`running_agent`, with the endpoint it says it listens on (a port ``*`` in
    its file becomes the one the system chose)."""
    command = btcap("--log-level", log_level, "agent", str(config), *flags)
    proc = await anyio.open_process(command, stdout=subprocess.PIPE, stderr=stderr)
    try:
        assert proc.stdout is not None
        said = b""
        while b"listening" not in said or not said.endswith(b"\n"):
            chunk = await proc.stdout.receive()
            said += chunk
        yield proc, said.decode().split(" listening on ")[1].split()[0]
    finally:
        with anyio.CancelScope(shield=True):
            if proc.returncode is None:
                proc.kill()
            await proc.aclose()


async def said_on_stderr(proc: anyio.abc.Process, text: str, so_far: bytes = b"") -> bytes:
    """What ``proc`` wrote on stderr up to and including ``text`` (it must be piped)."""
    assert proc.stderr is not None
    while text.encode() not in so_far:
        so_far += await proc.stderr.receive()
    return so_far


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
