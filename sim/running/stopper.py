"""Ending ``btcap run`` (and ``btcap sim serve``) on SIGINT/SIGTERM with a result, not a
traceback: shared by the commands that run a scenario."""

from __future__ import annotations

import signal
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import asyncio

    import anyio

__all__ = ["STOPPED_BY", "Stopper"]


#: What ``btcap run`` exits with when a signal stopped it (128 + the signal's number).
STOPPED_BY = {signal.SIGINT: 130, signal.SIGTERM: 143}


class Stopper:
    """SIGINT and SIGTERM end the run early, still with a result (marked ``interrupted``);
    a second signal acts as it would without us. Installed for the whole command, so a
    signal between two scenarios, or before the first starts, is not lost."""

    def __init__(self) -> None:
        self.signum: int | None = None
        self._event: anyio.Event | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._saved: dict[int, Any] = {}

    def __enter__(self) -> Stopper:
        for sig in STOPPED_BY:
            self._saved[sig] = signal.signal(sig, self._on_signal)
        return self

    def __exit__(self, *exc: object) -> None:
        self._restore()

    def _restore(self) -> None:
        saved, self._saved = self._saved, {}
        for sig, old in saved.items():
            signal.signal(sig, old)

    def _on_signal(self, signum: int, _frame: object) -> None:
        self.signum = signum
        self._restore()
        if self._loop is not None and self._event is not None:
            self._loop.call_soon_threadsafe(self._event.set)

    def event(self) -> anyio.Event:
        """The stop event of the scenario about to run in this event loop."""
        import asyncio

        import anyio

        self._loop = asyncio.get_running_loop()
        self._event = anyio.Event()
        if self.signum is not None:
            self._event.set()
        return self._event
