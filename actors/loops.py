"""The event loop a btcap process runs on: uvloop when it is installed, else asyncio's.

uvloop (the optional ``fast`` extra) makes an ask over tcp faster (docs/performance.md:
measured both ways in one run), so agents and the ``btcap team`` commands use it when it
is there; nothing requires it. ``BTCAP_LOOP=asyncio`` keeps the
stock loop, ``BTCAP_LOOP=uvloop`` insists on uvloop (an error if it is not installed).
A :class:`~btcap.actors.ManualClock` needs the stock loop (it reads its ready queue), so
runs on virtual time never come here.

Nothing may hold a robot's loop for more than ~50 ms (its heartbeats stop, its team
declares it failed). In asyncio's debug mode (``python -X dev``, which is also btcap's
debug mode, or ``PYTHONASYNCIODEBUG=1``; uvloop honours both) the loop times every
callback: :func:`report_stalls` lowers its threshold to :data:`STALL_S` and turns the
loop's "Executing ... took" warnings into one ``loop.stalled`` event per callback (its
name and seconds, on the ``btcap.actors.loops`` logger). An agent arms it as it starts.
``BTCAP_DEBUG`` alone does not turn asyncio's debug mode on: that mode records a
traceback for every callback scheduled.
"""

from __future__ import annotations

import asyncio
import logging
import os
import re
from collections.abc import Callable, Coroutine, Mapping
from typing import Any, TypeVar

from btcap.transports.log import get_logger

__all__ = ["LOOP_ENV", "STALL_S", "loop_factory", "loop_name", "report_stalls", "run"]

T = TypeVar("T")
#: A callback holding the loop longer than this (seconds) is a stall (see the module).
STALL_S = 0.05
#: Callback sites reported at most (each once): a bound on what a process remembers.
MAX_SITES = 1000
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


_log = get_logger(__name__)
#: The callback's name in asyncio's (and uvloop's) text for it: a task's coroutine, or a
#: handle's function (``<Handle Actor.method(args) ...>``, ``<TimerHandle when=1 f()>``).
_SITE = re.compile(r"coro=<([^\s(>]+)|^<(?:Timer)?Handle (?:when=\S+ )?([^\s(>]+)")


class _Stalls(logging.Filter):
    """On the ``asyncio`` logger: a slow-callback warning becomes one ``loop.stalled``
    event per callback site; its repeats and the original record are dropped."""

    def __init__(self) -> None:
        super().__init__()
        self.seen: set[str] = set()

    def filter(self, record: logging.LogRecord) -> bool:
        args = record.args
        if not (
            record.msg == "Executing %s took %.3f seconds"
            and isinstance(args, tuple)
            and len(args) == 2
        ):
            return True
        text, took = str(args[0]), args[1]
        seconds = float(took) if isinstance(took, int | float) else 0.0
        m = _SITE.search(text)
        site = (m.group(1) or m.group(2)) if m else text[:120]
        if site not in self.seen and len(self.seen) < MAX_SITES:
            self.seen.add(site)
            _log.warning(
                "loop.stalled",
                callback=site,
                seconds=round(seconds, 3),
                handle=text[:400],
                fix="run CPU work in a worker thread, import heavy modules before joining",
            )
        return False


def report_stalls(loop: asyncio.AbstractEventLoop, threshold_s: float = STALL_S) -> bool:
    """If ``loop`` runs in asyncio's debug mode: report callbacks over ``threshold_s``
    once per site as ``loop.stalled`` (see the module). Returns whether it is armed."""
    if not loop.get_debug():
        return False
    loop.slow_callback_duration = min(loop.slow_callback_duration, threshold_s)
    logger = logging.getLogger("asyncio")
    if not any(isinstance(f, _Stalls) for f in logger.filters):
        logger.addFilter(_Stalls())
    return True
