"""An agent's transport forgets a teammate its membership declared failed or gone: no
re-dialling, its sockets closed (issue 19, item 5). Real ZeroMQ on loopback, with keys
and without.

Judged by membership events, never by how long they took: a loaded machine may stall the
loop past the failure timeout, and a teammate declared failed while it still speaks comes
back; the test waits for the state it needs rather than asserting it at one moment, and
leaving needs no failure detection at all (a timeout no stall reaches)."""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

import anyio
import pytest

from btcap.actors import Clock
from btcap.team.core.members import TeamEvent
from btcap.team.runtime.agent import Agent, AgentConfig
from btcap.team.runtime.protocol import protocol_registry
from btcap.transports import ZmqTransport
from btcap.transports.security import write_key_pair

TCP = "tcp://127.0.0.1:*"
#: Failure detection only where the test needs it (b falls silent): short, so it is quick.
FAILING = AgentConfig(heartbeat_s=0.05, failure_timeout_s=0.6, lease_s=1.0)
#: A goodbye needs none: no stall of a loaded machine makes a false failure here.
LEAVING = AgentConfig(heartbeat_s=0.05, failure_timeout_s=600.0, lease_s=1.0)


def transport(name: str, keys: Path | None, **kw: Any) -> ZmqTransport:
    secure: dict[str, Any] = {}
    if keys is not None:
        secure = {"keys": keys / f"{name}.key_secret", "trusted": keys / "team"}
    return ZmqTransport(name, TCP, protocol_registry(), **secure, **kw)


@pytest.fixture(params=["keyless", "keyed"])
def keys(request: pytest.FixtureRequest, tmp_path: Path) -> Path | None:
    if request.param == "keyless":
        return None
    (tmp_path / "team").mkdir()
    for name in ("a", "b"):
        public, _ = write_key_pair(tmp_path, name)
        shutil.copy(public, tmp_path / "team" / public.name)
    return tmp_path


async def until(cond: Any) -> None:
    """Until ``cond()``; the test's fail_after bounds it."""
    while not cond():  # noqa: ASYNC110 - membership has no event for this
        await anyio.sleep(0.01)


@pytest.mark.parametrize("how", ["left", "failed"])
async def test_a_teammate_gone_is_forgotten_by_the_transport(keys: Path | None, how: str) -> None:
    config = FAILING if how == "failed" else LEAVING
    with anyio.fail_after(60):
        ta = transport("a", keys)
        tb = transport("b", keys, peers={"a": ta.endpoint})
        seen: list[tuple[TeamEvent, str]] = []
        try:
            async with Agent("a", transport=ta, clock=Clock(), config=config) as a:
                a.team.subscribe(lambda e, r: seen.append((e, r)))
                async with Agent("b", transport=tb, clock=Clock(), config=config):
                    # (b declared failed by a stall and back meanwhile: it is a peer again)
                    await until(lambda: "b" in a.team.members and "b" in ta.peers())
                    if how == "failed":
                        silent = len(seen)
                        tb.close()  # b falls silent without a goodbye
                        await until(lambda: (TeamEvent.FAILED, "b") in seen[silent:])
                        assert "b" not in ta.peers()  # forgotten: no more dialling
                if how == "left":
                    await until(lambda: (TeamEvent.LEFT, "b") in seen)
                assert "b" not in ta.peers()
                assert ta.peer_endpoints() == {}
        finally:
            ta.close()
            tb.close()
