"""A watcher for tests of moving work: no task may run unpaused on two robots at once."""

from __future__ import annotations

from typing import Any

import pytest

from btcap.team.core.hosting import HostLeases
from btcap.team.ids import ExecutionId

__all__ = ["watch_runs"]


def watch_runs(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """Every moment two robots run the same task (its node) with inputs, unpaused, as a
    list (a replacement holds its robot paused until its node adopts it)."""
    hosts: list[HostLeases[Any]] = []
    twice: list[str] = []
    init, inputs, release = HostLeases.__init__, HostLeases.inputs, HostLeases.release

    def check() -> None:
        nodes = [
            e.node
            for h in hosts
            for e, run in h.hosted.items()
            if h.body.running == e and not run.paused
        ]
        twice.extend(n for n in set(nodes) if nodes.count(n) > 1)

    def init_(self: HostLeases[Any], *args: Any, **kwargs: Any) -> None:
        init(self, *args, **kwargs)
        hosts.append(self)

    def inputs_(self: HostLeases[Any], *args: Any, **kwargs: Any) -> Any:
        out = inputs(self, *args, **kwargs)
        check()
        return out

    def release_(self: HostLeases[Any], execution: ExecutionId) -> Any:
        out = release(self, execution)
        check()
        return out

    monkeypatch.setattr(HostLeases, "__init__", init_)
    monkeypatch.setattr(HostLeases, "inputs", inputs_)
    monkeypatch.setattr(HostLeases, "release", release_)
    return twice
