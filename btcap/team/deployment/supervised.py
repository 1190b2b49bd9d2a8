"""A child process that never outlives its parent: it stops when its standard input closes.

A parent holding a pipe to the child's stdin closes it by exiting, even by SIGKILL, so a
robot started by a simulator or a test cannot linger after it.
"""

from __future__ import annotations

import asyncio
import os
import stat
import sys
from typing import Any

__all__ = ["stdin_closed", "watchable"]


def watchable(stream: Any) -> bool:
    """Whether ``stream`` can signal its end (a pipe, a socket or a terminal; not
    /dev/null or a file, whose end means nothing)."""
    try:
        mode = os.fstat(stream.fileno()).st_mode
    except (OSError, ValueError, AttributeError):
        return False
    return stat.S_ISFIFO(mode) or stat.S_ISSOCK(mode) or (stat.S_ISCHR(mode) and stream.isatty())


async def stdin_closed() -> None:
    """Return once standard input reaches its end (what arrives on it is discarded)."""
    loop = asyncio.get_running_loop()
    reader = asyncio.StreamReader()
    transport, _ = await loop.connect_read_pipe(
        lambda: asyncio.StreamReaderProtocol(reader), sys.stdin
    )
    try:
        while await reader.read(65536):
            pass
    finally:
        transport.close()
