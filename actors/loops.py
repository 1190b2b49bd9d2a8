"""The event loop a btcap process runs on: uvloop when it is installed, else asyncio's.

uvloop (the optional ``fast`` extra) makes an ask over tcp faster (docs/performance.md:
measured both ways in one run), so agents and the ``btcap team`` commands use it when it
is there; nothing requires it. ``BTCAP_LOOP=asyncio`` keeps the
stock loop, ``BTCAP_LOOP=uvloop`` insists on uvloop (an error if it is not installed).
A :class:`~btcap.actors.ManualClock` needs the stock loop (it reads its ready queue), so
runs on virtual time never come here.
"""

from __future__ import annotations

import asyncio
import os
from collections.abc import Callable, Coroutine, Mapping
from typing import Any, TypeVar

__all__ = ["LOOP_ENV", "loop_factory", "loop_name", "run"]

T = TypeVar("T")
LOOP_ENV = "BTCAP_LOOP"
_CHOICES = ("auto", "asyncio", "uvloop")


def _uvloop_installed() -> bool:
    try:
        import uvloop  # noqa: F401
    except ImportError:
        return False
    return True


def loop_name(env: Mapping[str, str] = os.environ) -> str:
    """``"uvloop"`` or ``"asyncio"``, as ``BTCAP_LOOP`` in ``env`` and what is installed say.

    Raises ValueError naming the variable for a value it does not know, or for uvloop
    asked for by name but not installed.
    """
    wanted = env.get(LOOP_ENV, "").strip().lower() or "auto"
    if wanted not in _CHOICES:
        raise ValueError(f"{LOOP_ENV}={wanted!r}: expected one of {', '.join(_CHOICES)}")
    if wanted == "asyncio":
        return "asyncio"
    if _uvloop_installed():
        return "uvloop"
    if wanted == "uvloop":
        raise ValueError(f"{LOOP_ENV}=uvloop: uvloop is not installed (pip install btcap[fast])")
    return "asyncio"


def loop_factory(env: Mapping[str, str] = os.environ) -> Callable[[], asyncio.AbstractEventLoop]:
    """What makes the loop :func:`loop_name` names (for ``asyncio.Runner`` or anyio's
    ``backend_options={"loop_factory": ...}``)."""
    if loop_name(env) == "uvloop":
        import uvloop

        return uvloop.new_event_loop
    return asyncio.new_event_loop


def run(coro: Coroutine[Any, Any, T], env: Mapping[str, str] = os.environ) -> T:
    """``asyncio.run(coro)`` on the loop :func:`loop_name` names."""
    try:
        factory = loop_factory(env)
    except ValueError:
        coro.close()
        raise
    with asyncio.Runner(loop_factory=factory) as runner:
        return runner.run(coro)
