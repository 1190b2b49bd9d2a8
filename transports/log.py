"""btcap's loggers: structlog front ends over standard ``logging`` loggers named ``btcap.*``.

A library stays silent unless the application asks for its logs, so nothing here
configures structlog or adds output. The application decides through the standard
``logging`` module (``logging.getLogger("btcap").setLevel(...)`` plus any handler), or
through structlog: once structlog is configured (by the application,
:func:`btcap.actors.configure_logging` or ``structlog.testing.capture_logs``), btcap's
events run through its processors before reaching the ``logging`` logger. Until then
they are plain ``logging`` records (``event key=value ...``), and a level that logger
would drop costs no formatting at all.

The lowest layer holds this so every layer can log the same way.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from typing import Any

import structlog
from structlog.stdlib import LOG_KWARG_NAMES, filter_by_level

__all__ = ["get_logger", "wanted", "worth_logging"]

# The documented habit of libraries: without it, Python's last-resort handler would
# print btcap's warnings to stderr in a program that configured no logging. What a user
# must see by default (a node's error, a capability nobody can take) is a Python warning
# instead (btcap.BtcapWarning's categories), which the standard filters quieten.
logging.getLogger("btcap").addHandler(logging.NullHandler())

_fields = structlog.processors.LogfmtRenderer()


class _Logger(structlog.stdlib.BoundLogger):
    """A stdlib BoundLogger that renders plainly while nobody configured structlog."""

    def _process_event(
        self, method_name: str, event: str | None, event_kw: dict[str, Any]
    ) -> tuple[Sequence[Any], Mapping[str, Any]]:
        if structlog.is_configured():
            return super()._process_event(method_name, event, event_kw)
        # Checked before any work: raises DropEvent for a level the logger would drop.
        filter_by_level(self._logger, method_name, {})
        fields = {**self._context, **event_kw}
        kwargs = {k: fields.pop(k) for k in LOG_KWARG_NAMES if k in fields}
        args = fields.pop("positional_args", ())
        text = _fields(self._logger, method_name, fields) if fields else ""
        message = f"{event} {text}" if text else str(event)
        return (message, *args), kwargs


def get_logger(name: str) -> Any:
    """The structlog logger btcap module ``name`` logs with (a ``btcap.*`` logging name).

    It follows structlog's configuration at every call, never a cached one, so a
    configuration made later (or a test's ``capture_logs``) applies to it.
    """
    return structlog.wrap_logger(
        logging.getLogger(name), wrapper_class=_Logger, cache_logger_on_first_use=False
    )


def wanted(name: str, level: int) -> bool:
    """Whether an event at ``level`` (a ``logging`` level) of btcap logger ``name`` goes
    anywhere, for a hot path to skip building one nobody keeps (structlog's call costs
    microseconds even for an event it drops): yes when the ``logging`` logger takes that
    level, or when structlog is configured without a level filter (as
    ``structlog.testing.capture_logs`` is)."""
    if logging.getLogger(name).isEnabledFor(level):
        return True
    return structlog.is_configured() and filter_by_level not in structlog.get_config()["processors"]


def worth_logging(count: int) -> bool:
    """Whether the ``count``-th occurrence of one kind of bad input gets a log line: the
    first ten, then every power of two, so a flood of junk is not a flood of lines."""
    return count <= 10 or count & (count - 1) == 0
