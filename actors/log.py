"""Log output for programs (the CLI, the benchmarks); the library itself configures none.

btcap logs through standard ``logging`` loggers named ``btcap.*`` (see
:mod:`btcap.transports.log`). An application that embeds btcap turns its logs on the
usual way, e.g. ``logging.basicConfig(level=logging.INFO)``; :func:`configure_logging`
is the one-call set-up for programs that want structlog's rendering.
"""

from __future__ import annotations

import logging
import os
import sys
from typing import TextIO

import structlog

__all__ = ["configure_logging"]


class _Handler(logging.StreamHandler):  # type: ignore[type-arg]
    """The handler configure_logging installs, so calling it again replaces it."""


def _colours(stream: TextIO) -> bool:
    """Colour codes only for a person at a terminal: a redirected log stays plain text.
    ``NO_COLOR`` and ``FORCE_COLOR`` (https://no-color.org) override the guess."""
    if os.environ.get("NO_COLOR"):
        return False
    if os.environ.get("FORCE_COLOR"):
        return True
    isatty = getattr(stream, "isatty", None)
    return bool(isatty is not None and isatty())


def configure_logging(level: str | int = "info", *, json: bool = False) -> None:
    """Send log records of ``level`` and above to stderr: readable console lines or JSON.

    Sets up the root ``logging`` logger with a structlog formatter, so btcap's events and
    any other library's records come out alike, and configures structlog to hand its
    events to ``logging``. Console lines are coloured only when stderr is a terminal.
    Meant for a program's entry point: it changes global state.
    """
    numeric = logging.getLevelName(level.upper()) if isinstance(level, str) else level
    if not isinstance(numeric, int):
        raise ValueError(f"log level {level!r}: expected debug, info, warning or error")
    timestamper = structlog.processors.TimeStamper(fmt="iso")
    shared: list[structlog.typing.Processor] = [
        structlog.stdlib.add_log_level,
        structlog.stdlib.add_logger_name,
        timestamper,
    ]
    stream = sys.stderr
    renderer: structlog.typing.Processor = (
        structlog.processors.JSONRenderer()
        if json
        else structlog.dev.ConsoleRenderer(colors=_colours(stream))
    )
    handler = _Handler(stream)
    handler.setFormatter(
        structlog.stdlib.ProcessorFormatter(
            foreign_pre_chain=shared,  # records of plain ``logging`` loggers
            processors=[
                structlog.stdlib.ProcessorFormatter.remove_processors_meta,
                *([structlog.processors.format_exc_info] if json else []),
                renderer,
            ],
        )
    )
    root = logging.getLogger()
    for old in [h for h in root.handlers if isinstance(h, _Handler)]:
        root.removeHandler(old)
    root.addHandler(handler)
    root.setLevel(numeric)
    structlog.configure(
        processors=[
            structlog.contextvars.merge_contextvars,
            structlog.stdlib.filter_by_level,
            *shared,
            structlog.processors.StackInfoRenderer(),
            structlog.stdlib.ProcessorFormatter.wrap_for_formatter,
        ],
        logger_factory=structlog.stdlib.LoggerFactory(),
        wrapper_class=structlog.stdlib.BoundLogger,
        cache_logger_on_first_use=False,
    )
