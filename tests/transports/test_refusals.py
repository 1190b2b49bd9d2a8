"""Failed handshakes are told on both machines, in a line saying what to check, and a
refused link is dialled again at a falling pace, not in a storm.

Loopback only (OS-chosen tcp ports); every transport is closed.
"""

from __future__ import annotations

import contextlib
import shutil
import warnings
from collections.abc import AsyncIterator, Callable
from pathlib import Path
from typing import Any

import anyio
import pytest
import zmq
from structlog.testing import capture_logs

from btcap.actors import ActorSystem
from btcap.transports import KeyPair, TransportStats, ZmqTransport
from btcap.transports.refusals import Refusals, fingerprint
from btcap.transports.security import write_key_pair
from tests.transports.peer_process import messages

LOCAL = "tcp://127.0.0.1:*"


@pytest.fixture
def keys(tmp_path: Path) -> Path:
    """alpha's team trusts alpha only; the operator's folder holds alpha and itself."""
    for folder in ("team", "ours", "old"):
        (tmp_path / folder).mkdir()
    for name in ("alpha", "operator"):
        public, _ = write_key_pair(tmp_path, name)
        shutil.copy(public, tmp_path / "ours" / public.name)
        if name == "alpha":
            shutil.copy(public, tmp_path / "team" / public.name)
    write_key_pair(tmp_path / "old", "alpha")  # a key alpha once had
    return tmp_path


@contextlib.asynccontextmanager
async def both(alpha: ZmqTransport, operator: ZmqTransport) -> AsyncIterator[None]:
    try:
        async with (
            ActorSystem(transport=alpha, registry=messages()),
            ActorSystem(transport=operator, registry=messages()),
        ):
            yield
    finally:
        operator.close()
        alpha.close()


def keyed(name: str, keys: Path, trusted: str, **kwargs: Any) -> ZmqTransport:
    secret = keys / f"{name}.key_secret"
    return ZmqTransport(name, LOCAL, messages(), keys=secret, trusted=keys / trusted, **kwargs)


async def logged(logs: list[dict[str, Any]], event: str) -> dict[str, Any]:
    """The first ``event`` logged, waited for (at most 5 s)."""
    with anyio.fail_after(5):
        while True:
            for entry in logs:
                if entry["event"] == event:
                    return entry
            await anyio.sleep(0.01)


async def test_a_refused_key_is_told_on_both_machines_and_redialled_slowly(keys: Path) -> None:
    with capture_logs() as logs, anyio.fail_after(10):
        alpha = keyed("alpha", keys, "team")
        operator = keyed("operator", keys, "ours", peers={"alpha": alpha.endpoint})
        async with both(alpha, operator):
            ours = await logged(logs, "transport.handshake_refused")
            theirs = await logged(logs, "transport.key_refused")
            assert ours["log_level"] == theirs["log_level"] == "warning"
            assert ours["peer"] == "alpha"
            assert ours["endpoint"] == alpha.endpoint
            assert ours["detail"] == (
                "alpha refused our key: is operator.key in its trusted folder "
                "(keys.trusted in alpha's config file)?"
            )
            assert operator.stats.refused_by == {"alpha": ours["detail"]}
            public = KeyPair.load(keys / "operator.key_secret").public
            assert theirs["address"] == "127.0.0.1"
            assert theirs["key"] == fingerprint(public) == public.decode()[:8] + "\u2026"
            assert theirs["known_as"] == "unknown"
            assert "not in our trusted folder (keys.trusted)" in theirs["detail"]
            await anyio.sleep(0.5)  # dialled again after 0.25 s, 0.5 s, 1 s ...
            tries = alpha.stats.by_reason["handshake refused"]
            assert 1 <= tries <= 5, "re-dialled in a storm"
        lines = [e["event"] for e in logs if e["event"].endswith(("_refused", "_failed"))]
        assert sorted(lines) == ["transport.handshake_refused", "transport.key_refused"]


async def test_a_stale_copy_of_a_teammates_key_is_told_on_both_machines(keys: Path) -> None:
    shutil.copy(keys / "old" / "alpha.key", keys / "ours" / "alpha.key")
    shutil.copy(keys / "operator.key", keys / "team" / "operator.key")
    with capture_logs() as logs, anyio.fail_after(10):
        alpha = keyed("alpha", keys, "team")
        operator = keyed("operator", keys, "ours", peers={"alpha": alpha.endpoint})
        async with both(alpha, operator):
            ours = await logged(logs, "transport.handshake_refused")
            theirs = await logged(logs, "transport.handshake_failed")
    assert "does alpha.key in our trusted folder (keys.trusted)" in ours["detail"]
    assert "an old copy of our public key (alpha.key in its trusted folder)" in theirs["detail"]


async def test_a_robot_without_keys_is_told_to_add_them(keys: Path) -> None:
    with capture_logs() as logs, anyio.fail_after(10):
        alpha = keyed("alpha", keys, "team")
        plain = ZmqTransport("operator", LOCAL, messages(), peers={"alpha": alpha.endpoint})
        async with both(alpha, plain):
            ours = await logged(logs, "transport.handshake_refused")
            theirs = await logged(logs, "transport.handshake_failed")
    # (libzmq tells it the mechanism mismatch, or hangs up first and says nothing)
    assert ours["detail"].startswith(f"alpha at {alpha.endpoint} wants keys")
    assert "we have none: add keys: {secret: operator.key_secret" in ours["detail"]
    assert "btcap keys new operator" in ours["detail"]
    assert theirs["detail"].startswith("a peer without keys tried to connect")


def test_lines_are_rate_limited_per_peer_and_cleared_once_admitted() -> None:
    now = [0.0]
    clock: Callable[[], float] = lambda: now[0]  # noqa: E731
    stats = TransportStats()
    refusals = Refusals("operator", stats, b"k" * 40, quiet_s=60.0, max_entries=4, clock=clock)
    refused = int(zmq.EVENT_HANDSHAKE_FAILED_AUTH)
    with capture_logs() as logs:
        pauses = [refusals.failed("alpha", "tcp://h:1", refused, 400) for _ in range(12)]
        now[0] = 61.0
        refusals.failed("alpha", "tcp://h:1", refused, 400)
        refusals.admitted("alpha")
    assert pauses[:4] == [0.25, 0.5, 1.0, 2.0]
    assert max(pauses) == 30.0
    assert [(e["event"], e.get("count")) for e in logs] == [
        ("transport.handshake_refused", 1),
        ("transport.handshake_refused", 12),  # the 13th and the 12 since the first line
        ("transport.handshake_admitted", None),
    ]
    assert stats.refused_by == {}
    with capture_logs() as logs:
        for i in range(100):  # anyone can present any number of keys: the table stays small
            refusals.we_refused("10.0.0.9", f"{i:040d}".encode())
        refusals.we_refused("10.0.0.9", f"{99:040d}".encode())  # remembered: quiet
        refusals.we_refused("10.0.0.9", f"{0:040d}".encode())  # forgotten: told again
    assert len(logs) == 101
    assert logs[-1]["key"] == "00000000\u2026"


async def test_a_refused_key_is_a_warning_on_both_machines_once_without_logging(
    keys: Path,
) -> None:
    """A program that configured no logging (btcap's loggers end in a NullHandler) still
    hears of a refused key, on both sides, once each however often it is re-dialled: a
    HandshakeWarning (a BtcapWarning) saying what to check; filters quieten it."""
    from btcap import BtcapWarning, HandshakeWarning

    assert issubclass(HandshakeWarning, BtcapWarning)
    with warnings.catch_warnings(record=True) as caught, anyio.fail_after(15):
        warnings.simplefilter("always")
        alpha = keyed("alpha", keys, "team")
        operator = keyed("operator", keys, "ours", peers={"alpha": alpha.endpoint})
        async with both(alpha, operator):
            refused = alpha.stats.by_reason
            with anyio.fail_after(8):  # told, then dialled again twice (0.25 s, 0.5 s on)
                for _ in range(2000):
                    if len(_handshake(caught)) >= 2 and refused.get("handshake refused", 0) >= 3:
                        break
                    await anyio.sleep(0.01)
    told = _handshake(caught)
    assert len(told) == 2, told
    ours = next(t for t in told if "refused our key" in t)
    theirs = next(t for t in told if "not in our trusted folder" in t)
    assert ours.startswith("operator: alpha refused our key: is operator.key in its trusted")
    assert theirs.startswith("alpha: refused 127.0.0.1: its key ")


def _handshake(caught: list[warnings.WarningMessage]) -> list[str]:
    from btcap import HandshakeWarning

    return [str(w.message) for w in caught if issubclass(w.category, HandshakeWarning)]
