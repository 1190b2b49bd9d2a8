"""Revocation without restarts: a key removed from the trusted folder is refused for new
connections and its existing links are closed; a key added is admitted.

CURVE over tcp loopback (OS-chosen ports), the folder polled every 20 ms; every transport
is closed. The test waits for events (counters, peer lists), never for the poll period.
"""

from __future__ import annotations

import contextlib
import shutil
from collections.abc import Iterator
from pathlib import Path

import anyio
import pytest
from structlog.testing import capture_logs

from btcap.actors import Address
from btcap.transports import ZmqTransport
from btcap.transports.security import write_key_pair
from btcap.transports.trust import listing
from tests.transports.peer_process import Echo, Echoed
from tests.transports.test_security import eventually, secure, serving

POLL_S = 0.02


@pytest.fixture
def keys(tmp_path: Path) -> Path:
    """Key pairs for a, b, mallory and late; team/ holds all but late's."""
    team = tmp_path / "team"
    team.mkdir()
    for name in ("a", "b", "mallory", "late"):
        public, _ = write_key_pair(tmp_path, name)
        if name != "late":
            shutil.copy(public, team / public.name)
    return tmp_path


@pytest.fixture
def logs() -> Iterator[list[dict[str, object]]]:
    with capture_logs() as captured:
        yield captured


async def test_a_removed_key_is_refused_and_its_links_closed(
    keys: Path, logs: list[dict[str, object]]
) -> None:
    with anyio.fail_after(20):
        async with contextlib.AsyncExitStack() as stack:
            ta = secure("a", keys, trusted_poll_s=POLL_S)
            a = await stack.enter_async_context(serving(ta))
            echo = Address("a", "echo")
            # Their own folders do not change (poll 0): only a revokes.
            tb = secure("b", keys, peers={"a": ta.endpoint}, trusted_poll_s=0)
            b = await stack.enter_async_context(serving(tb))
            tm = secure("mallory", keys, peers={"a": ta.endpoint}, trusted_poll_s=0)
            m = await stack.enter_async_context(serving(tm))
            assert await m.ref(echo).ask(Echo("hi"), timeout=5) == Echoed("hi", "a")
            await eventually(lambda: {"b", "mallory"} <= ta.peers(), "a dialled both back")

            (keys / "team" / "mallory.key").unlink()
            await eventually(lambda: "mallory" not in ta.peers(), "a closed its link to her")
            assert ta.curve is not None
            assert "mallory" not in ta.curve.team
            # Her link into a: what she sends is dropped and the connection cut; her
            # DEALER dials again and ZAP refuses the key.
            disconnects = ta.disconnects
            received = ta.stats.received
            m.tell(echo, Echo("still here?"))
            await eventually(lambda: ta.stats.by_reason.get("key revoked", 0) >= 1, "dropped")
            await eventually(lambda: ta.disconnects > disconnects, "her connection cut")
            await eventually(
                lambda: ta.stats.by_reason.get("handshake refused", 0) >= 1, "redial refused"
            )
            with pytest.raises(TimeoutError):
                await m.ref(echo).ask(Echo("again"), timeout=0.3)
            assert ta.stats.received == received  # nothing of hers delivered
            # A new process with her key (and her stale copy of the folder) gets nowhere.
            assert tm.curve is not None
            fresh = ZmqTransport(
                "mallory",
                "tcp://127.0.0.1:*",
                tm.codec.registry,
                keys=keys / "mallory.key_secret",
                trusted=tm.curve.team,
                peers={"a": ta.endpoint},
                trusted_poll_s=0,
            )
            refused = ta.stats.by_reason["handshake refused"]
            m2 = await stack.enter_async_context(serving(fresh))
            await eventually(
                lambda: ta.stats.by_reason["handshake refused"] > refused, "fresh one refused"
            )
            with pytest.raises(TimeoutError):
                await m2.ref(echo).ask(Echo("new me"), timeout=0.3)
            # b is untouched, both ways.
            assert await b.ref(echo).ask(Echo("b"), timeout=5) == Echoed("b", "a")
            assert await a.ref(Address("b", "echo")).ask(Echo("a"), timeout=5) == Echoed("a", "b")
    reloaded = [e for e in logs if e["event"] == "transport.trusted_reloaded"]
    assert [e["revoked"] for e in reloaded] == [["mallory"]]


async def test_a_key_added_is_admitted_and_a_broken_folder_changes_nothing(
    keys: Path, logs: list[dict[str, object]]
) -> None:
    with anyio.fail_after(20):
        async with contextlib.AsyncExitStack() as stack:
            ta = secure("a", keys, trusted_poll_s=POLL_S)
            await stack.enter_async_context(serving(ta))
            assert ta.curve is not None
            # A broken certificate: the folder does not load; a keeps its keys.
            (keys / "team" / "late.tmp").write_text("not a certificate\n")
            (keys / "team" / "late.tmp").replace(keys / "team" / "late.key")
            await eventually(
                lambda: any(e["event"] == "transport.trusted_not_reloaded" for e in logs),
                "the reload failure said",
            )
            assert set(ta.curve.team) == {"a", "b", "mallory"}
            # Copied in as the docs say: under another name, then renamed (never half-read).
            shutil.copy(keys / "late.key", keys / "team" / "late.tmp")
            (keys / "team" / "late.tmp").replace(keys / "team" / "late.key")
            curve = ta.curve
            await eventually(lambda: "late" in curve.team, "late's key admitted")
            tl = ZmqTransport(
                "late",
                "tcp://127.0.0.1:*",
                ta.codec.registry,
                keys=keys / "late.key_secret",
                trusted=keys / "team",
                peers={"a": ta.endpoint},
                trusted_poll_s=0,
            )
            late = await stack.enter_async_context(serving(tl))
            reply = await late.ref(Address("a", "echo")).ask(Echo("hello"), timeout=5)
            assert reply == Echoed("hello", "a")
    failures = [e for e in logs if e["event"] == "transport.trusted_not_reloaded"]
    assert len(failures) == 1  # said once, not at every poll
    assert "late.key" in str(failures[0]["detail"])


def test_the_listing_sees_removal_and_rewrite(keys: Path) -> None:
    team = keys / "team"
    before = listing(team)
    assert [n for n, _, _ in before] == ["a.key", "b.key", "mallory.key"]
    (team / "b.key").unlink()
    assert [n for n, _, _ in listing(team)] == ["a.key", "mallory.key"]
    assert listing(keys / "nowhere") == ()


async def test_a_key_removed_before_serving_starts_is_still_revoked(keys: Path) -> None:
    """The watch compares with the folder as the keys were loaded, not as it is when
    serving starts (on a loaded machine that gap is long): a key removed in between is
    refused all the same."""
    with anyio.fail_after(20):
        ta = secure("a", keys, trusted_poll_s=POLL_S)
        (keys / "team" / "mallory.key").unlink()
        async with serving(ta):
            curve = ta.curve
            assert curve is not None
            await eventually(lambda: "mallory" not in curve.team, "mallory's key dropped")
