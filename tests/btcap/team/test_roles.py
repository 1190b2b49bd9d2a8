"""Roles in the trust list, observers that are not members, one live process per name.

ZeroMQ transports over tcp loopback (OS-chosen ports), with CURVE keys and without; the
receiving transport is given the team's role table (:func:`btcap.team.membership.roles.role_table`)
and what it delivers is recorded. Every transport is closed.
"""

from __future__ import annotations

import contextlib
import shutil
from collections.abc import AsyncIterator, Callable
from pathlib import Path
from typing import Any

import anyio
import pytest
from structlog.testing import capture_logs

from btcap.bt.messages import Tick
from btcap.team.ids import AuctionId, ExecutionId
from btcap.team.membership.roles import role_table
from btcap.team.messages import (
    ActivityQuery,
    Award,
    Bid,
    CallForBids,
    DeparturesQuery,
    ExecutionStatus,
    Heartbeat,
    ProbeRequest,
    RunState,
    StatusQuery,
    Vouch,
)
from btcap.team.runtime.protocol import protocol_registry
from btcap.transports import Address, Envelope, Kind, Message, TeamKeys, ZmqTransport
from btcap.transports.identity import observer_id, read_role
from btcap.transports.log import worth_logging
from btcap.transports.security import write_key_pair
from btcap.transports.zmq_claims import NameTaken

LOCAL = "tcp://127.0.0.1:*"
REFUSED = "not allowed for its role"
ROLES = {"r": "robot", "s": "robot", "op": "operator", "eye": "observer"}

_AUCTION = AuctionId("op", 1)
_RUN = ExecutionId("op", "m/greet", 1)
#: One message of each kind that matters, and who may send it.
TRIES: list[tuple[Message, set[str]]] = [
    (Heartbeat("x", 1, 0), {"robot", "operator"}),
    (CallForBids(_AUCTION, "Greet", "Greet:1", {}), {"robot", "operator"}),
    (Award(_AUCTION, _RUN, "Greet", "greet", {}, 1.0), {"robot", "operator"}),
    (Bid(_AUCTION, "x", 1.0, "greet"), {"robot"}),
    (ExecutionStatus(_RUN, "x", RunState.RUNNING, {}), {"robot"}),
    (Tick(), {"robot"}),
    (StatusQuery(), {"robot", "operator", "observer"}),
    (ActivityQuery(), {"robot", "operator", "observer"}),
    (DeparturesQuery(), {"robot", "operator", "observer"}),
    # an operator is a member: it probes and is probed like any robot
    (ProbeRequest("x", 1), {"robot", "operator"}),
    (Vouch("x", 1, 1, 1), {"robot", "operator"}),
]


@pytest.fixture
def keys(tmp_path: Path) -> Path:
    """A key pair per member (ROLES), their public certificates in team/."""
    team = tmp_path / "team"
    team.mkdir()
    for name, role in ROLES.items():
        public, _ = write_key_pair(tmp_path, name, role)
        shutil.copy(public, team / public.name)
    return tmp_path


def make(name: str, keys: Path | None, **kwargs: Any) -> ZmqTransport:
    member = name.partition("+")[0]
    return ZmqTransport(
        name,
        LOCAL,
        protocol_registry(),
        keys=None if keys is None else keys / f"{member}.key_secret",
        trusted=None if keys is None else keys / "team",
        **kwargs,
    )


@contextlib.asynccontextmanager
async def serving(
    *transports: ZmqTransport, got: list[Envelope] | None = None
) -> AsyncIterator[None]:
    """Serve every transport (the role table on each), recording what the first delivers."""
    try:
        async with anyio.create_task_group() as tg:
            for i, t in enumerate(transports):
                t.limit(role_table())
                record = got.append if i == 0 and got is not None else (lambda _e: None)
                await tg.start(t.serve, record)
            yield
            tg.cancel_scope.cancel()
    finally:
        for t in transports:
            t.close()


async def eventually(predicate: Callable[[], bool], what: str, within: float = 5.0) -> None:
    with anyio.fail_after(within):
        while not predicate():  # noqa: ASYNC110 - counters have no event to wait on
            await anyio.sleep(0.005)
    assert predicate(), what


def tell(sender: ZmqTransport, to: str, msg: Message) -> None:
    sender.send(Envelope(Kind.TELL, Address(sender.system_id, "x"), Address(to, "p"), msg))


async def _try_everything(keys: Path | None, senders: dict[str, str]) -> None:
    """Each sender (id -> the role it should be limited to) sends every message of
    TRIES to r; exactly what its role allows is delivered, the rest counted and logged."""
    got: list[Envelope] = []
    r = make("r", keys)
    others = [make(name, keys, peers={"r": r.endpoint}) for name in senders]
    with capture_logs() as logs, anyio.fail_after(10):
        async with serving(r, *others, got=got):
            for sender in others:
                for msg, _ in TRIES:
                    tell(sender, "r", msg)
            refused = sum(1 for role in senders.values() for _, ok in TRIES if role not in ok)
            expect = len(senders) * len(TRIES) - refused
            await eventually(
                lambda: len(got) + r.stats.by_reason.get(REFUSED, 0) >= len(senders) * len(TRIES),
                "all seen",
            )
    assert r.stats.by_reason.get(REFUSED, 0) == refused
    assert len(got) == expect
    for name, role in senders.items():
        delivered = [type(e.msg) for e in got if e.sender.system == name]
        assert delivered == [type(m) for m, ok in TRIES if role in ok], name
    lines = [e for e in logs if e.get("reason") == REFUSED]
    assert lines
    assert sum(worth_logging(n) for n in range(1, refused + 1)) == len(lines)
    assert any("may not send Bid" in e["detail"] for e in lines)


async def test_with_keys_each_role_sends_only_what_the_table_allows(keys: Path) -> None:
    senders = {"s": "robot", "op": "operator", "eye": "observer", "op+status-1a2b3c": "observer"}
    await _try_everything(keys, senders)


async def test_without_keys_everyone_is_everything_but_a_declared_observer() -> None:
    senders = {"s": "robot", "op": "robot", "eye+status-1a2b3c": "observer"}
    await _try_everything(None, senders)


def test_roles_are_read_from_the_certificates_and_checked(keys: Path, tmp_path: Path) -> None:
    team = TeamKeys.load(keys / "team")
    assert {n: team.role_of(n) for n in ROLES} == ROLES
    assert team.role_of("op+status-1") == "observer"  # an observer, whatever its key
    assert team.role_of("nobody") is None
    assert read_role(keys / "op.key_secret") == "operator"
    with pytest.raises(ValueError, match=r"role 'pilot': expected one of robot, operator"):
        write_key_pair(tmp_path, "pilot", "pilot")
    with pytest.raises(ValueError, match=r"reserved for observers"):
        write_key_pair(tmp_path, "a+b", "robot")
    cert = keys / "team" / "s.key"
    cert.write_text(cert.read_text().replace('role = "robot"', 'role = "admin"'))
    with pytest.raises(ValueError, match=r"s\.key: role 'admin'"):
        TeamKeys.load(keys / "team")


async def test_broadcasts_skip_observers_and_observers_are_not_kept(keys: Path) -> None:
    """An observer asks; team news (heartbeats, goodbyes) is never broadcast to it, and
    a silent one is forgotten like any stranger."""
    got: list[Envelope] = []
    eye = make(observer_id("op", "status"), keys)
    s = make("s", keys)
    r = make("r", keys, stranger_ttl_s=0.5)
    eye.add_peer("r", r.endpoint)
    s.add_peer("r", r.endpoint)
    with anyio.fail_after(10):
        async with serving(eye, s, r, got=got):
            tell(eye, "r", StatusQuery())
            await eventually(lambda: {"s", eye.system_id} <= r.peers(), "r met both")
            tell(s, "r", Heartbeat("s", 1, 0))  # s is vouched for; the observer is not
            r.send(
                Envelope(
                    Kind.TELL, Address("r", "team"), Address("*", "team"), Heartbeat("r", 1, 0)
                )
            )
            await eventually(lambda: s.stats.received >= 1, "s heard the broadcast")
            await anyio.sleep(0.1)
            assert got == []  # nothing broadcast reached the observer
            await eventually(lambda: eye.system_id not in r.peers(), "r forgot the observer")
            assert "s" in r.peers()


# -- one live process per name ----------------------------------------------------------
@pytest.mark.parametrize("keyed", [True, False], ids=["keys", "keyless"])
async def test_a_second_live_process_is_refused_and_told_why(keyed: bool, keys: Path) -> None:
    folder = keys if keyed else None
    got: list[Envelope] = []
    r = make("r", folder)
    first = make("s", folder, peers={"r": r.endpoint})
    with capture_logs() as logs, anyio.fail_after(10):
        async with serving(r, first, got=got):
            await eventually(lambda: r.endpoint_of("s") == first.endpoint, "r met s")
            tell(first, "r", Heartbeat("s", 1, 0))
            await eventually(lambda: len(got) == 1, "r heard s")
            second = make("s", folder, peers={"r": r.endpoint})
            try:
                tell(second, "r", Heartbeat("s", 2, 0))  # queued behind its hello
                with pytest.raises(NameTaken) as info:  # serve() ends, refused
                    await second.serve(lambda _e: None, task_status=anyio.TASK_STATUS_IGNORED)
            finally:
                second.close()
            await anyio.sleep(0.2)
            assert r.endpoint_of("s") == first.endpoint  # the live one keeps its place
            tell(first, "r", Heartbeat("s", 1, 0))
            await eventually(lambda: len(got) >= 2, "s still heard")
    why = str(info.value)
    assert why.startswith("r refused us: s is already live at " + first.endpoint)
    assert why.endswith("; stop it or use another name")
    assert "(since 20" in why
    if keyed:  # the second one's heartbeat never counted as the first one's
        assert [e.msg.incarnation for e in got if isinstance(e.msg, Heartbeat)] == [1, 1]
    taken = [e for e in logs if e["event"] == "transport.name_taken" and e["system"] == "r"]
    assert len(taken) == 1
    assert taken[0]["newcomer"] == second.endpoint


@pytest.mark.parametrize("keyed", [True, False], ids=["keys", "keyless"])
async def test_a_restarted_process_is_followed_to_its_new_endpoint(keyed: bool, keys: Path) -> None:
    folder = keys if keyed else None
    got: list[Envelope] = []
    r = make("r", folder)
    first = make("s", folder, peers={"r": r.endpoint})
    with anyio.fail_after(10), capture_logs() as logs:
        async with serving(r, got=got):
            heard: list[Envelope] = []
            async with serving(first, got=heard):
                await eventually(lambda: r.endpoint_of("s") == first.endpoint, "r met s")
                # r's own link to s is up (else its closing may come before r dialled it,
                # and there is no link to see drop: a race a loaded machine loses)
                tell(r, "s", Heartbeat("r", 1, 0))
                await eventually(lambda: len(heard) == 1, "s heard r")
            # The first one died (its sockets closed) and r saw its link drop (a real
            # restart takes longer than that; a hello racing the drop is a second process
            # as far as r can tell); a new life elsewhere says hello.
            await eventually(
                lambda: any(
                    e["event"] == "transport.peer_relinked" and e.get("peer") == "s" for e in logs
                ),
                "r saw the first one's link drop",
            )
            again = make("s", folder, peers={"r": r.endpoint})
            async with serving(again):
                await eventually(lambda: r.endpoint_of("s") == again.endpoint, "followed")
                tell(again, "r", Heartbeat("s", 2, 0))
                await eventually(lambda: len(got) == 1, "the new life is heard")
                assert again.name_taken is None


async def test_a_refusal_that_answers_no_hello_is_ignored(monkeypatch: pytest.MonkeyPatch) -> None:
    """Without keys anyone local can send a refusal in a teammate's name: one that comes
    long after our link to that teammate came up answers no hello of ours, and is dropped."""
    monkeypatch.setattr("btcap.transports.zmq_rules._ANSWER_S", 0.2)
    r = make("r", None)
    s = make("s", None, peers={"r": r.endpoint})
    with anyio.fail_after(10):
        async with serving(r, s):
            await eventually(lambda: r.endpoint_of("s") == s.endpoint, "r met s")
            await anyio.sleep(0.3)
            forger = make("r", None)  # r's name, its own socket: a refusal "from r"
            try:
                forger.add_peer("s", s.endpoint)
                forger._claims.refuse(  # what a real refusal sends, long after the hello
                    forger._ctx, None, b"r", "s", s.endpoint, r.endpoint, 0.0, None
                )
                await eventually(lambda: s.stats.by_reason.get("bad refusal", 0) == 1, "dropped")
            finally:
                forger._claims.done_telling()
                forger.close()
            assert s.name_taken is None
