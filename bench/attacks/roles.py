"""Attack probe, roles and names: members that send what their role does not allow, an
observer that pretends to be more, and a second process under a live robot's name.

A keyed team over tcp loopback in this process: ``origin`` (an operator key) ticks an
Echo mission run by ``r1`` (a robot key). Attackers hold real team keys:

- ``eye`` (an observer key) and ``op+x`` (an operator's key, as an observer id) try to
  start a mission on ``r1`` (call for bids, award), join (heartbeat), drive the run
  (inputs, cancel) and tick a node;
- ``op`` (an operator key) bids and reports on the origin's run as if it executed it;
- a second ``r1`` (r1's own key, another endpoint) says hello to the origin.

Every message must be refused by role (counted, logged at a falling rate), the second
``r1`` told why and stopped, and the mission must finish on ``r1`` untouched. Hooked into
:mod:`btcap.bench.attacks.probe` (``python -m btcap.bench attacks --quick`` runs it in CI).
"""

from __future__ import annotations

import asyncio
import contextlib
import tempfile
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

from btcap.bench.attacks.echo import echo_mission, echo_team, until
from btcap.bench.attacks.hostile import registry
from btcap.bt.messages import Tick
from btcap.bt.state import State
from btcap.team.core.members import TeamEvent
from btcap.team.demo import ECHO
from btcap.team.ids import AuctionId, ExecutionId
from btcap.team.membership.roles import role_table
from btcap.team.messages import (
    Award,
    Bid,
    CallForBids,
    CancelExecution,
    ExecutionInputs,
    ExecutionStatus,
    Heartbeat,
    RunState,
)
from btcap.team.runtime.agent import Agent, AgentConfig
from btcap.transports import Address, Envelope, Kind, Message, ZmqTransport
from btcap.transports.security import write_key_pair
from btcap.transports.zmq_claims import NameTaken

__all__ = ["probe_roles"]

_TCP = "tcp://127.0.0.1:*"
_REFUSED = "not allowed for its role"
_KEYS = {"r1": "robot", "origin": "operator", "op": "operator", "eye": "observer"}
_CONFIG = AgentConfig(heartbeat_s=0.1, failure_timeout_s=3.0, lease_s=3.0, keepalive_s=0.5)

Result = tuple[str, bool, dict[str, Any]]


def _transport(name: str, keys: Path) -> ZmqTransport:
    member = name.partition("+")[0]
    return ZmqTransport(name, _TCP, registry(), keys=keys / f"{member}.key_secret", trusted=keys)


@contextlib.asynccontextmanager
async def _serving(transport: ZmqTransport) -> AsyncIterator[ZmqTransport]:
    transport.limit(role_table())
    task = asyncio.create_task(transport.serve(lambda _e: None, task_status=_Ignored()))
    try:
        yield transport
    finally:
        transport.close()
        with contextlib.suppress(NameTaken, asyncio.CancelledError):
            await task


class _Ignored:
    def started(self, value: object = None) -> None:
        del value


def _send(sender: ZmqTransport, to: Address, msg: Message) -> None:
    sender.send(Envelope(Kind.TELL, Address(sender.system_id, "x"), to, msg))


async def probe_roles(quick: bool) -> list[Result]:
    """One result per attack, and one for the mission beside them."""
    del quick  # a handful of messages each: the same in both modes
    with tempfile.TemporaryDirectory(prefix="btcap-roles-") as tmp:
        keys = Path(tmp)
        for name, role in _KEYS.items():
            write_key_pair(keys, name, role)
        return await _probe(keys)


async def _probe(keys: Path) -> list[Result]:
    results: list[Result] = []
    t1, to = _transport("r1", keys), _transport("origin", keys)
    failures: list[str] = []
    async with echo_team(t1, to, _CONFIG) as (r1, origin):
        origin.team.subscribe(
            lambda ev, who: (
                failures.append(f"{ev.value}:{who}")
                if ev in (TeamEvent.FAILED, TeamEvent.LEFT)
                else None
            )
        )
        await until(lambda: "r1" in origin.repository.providers(ECHO.identity), 10.0)
        async with echo_mission(origin) as mission:
            node, tree = mission.node, mission.tree
            await until(lambda: node.state is State.RUNNING, 10.0)
            run = next(iter(origin.mission_control.active), ExecutionId("origin", "x", 1))
            auction = AuctionId("eye", 1)
            grab: list[Message] = [
                CallForBids(auction, ECHO.name, ECHO.identity, {"value": 9}),
                Award(auction, ExecutionId("eye", "m", 1), ECHO.name, "echo", {"value": 9}, 1e6),
                Heartbeat("eye", 1, 0),
                ExecutionInputs(run, 99, {"value": 666}),
                CancelExecution(run, "mine now"),
                Tick({"stop": True}),
            ]
            for who in ("eye", "op+x"):
                results.append(await _refused_all(who, keys, t1, r1, grab, failures))
            forged: list[Message] = [
                Bid(AuctionId("origin", 1), "op", 0.0, "echo"),
                ExecutionStatus(run, "op", RunState.SUCCEEDED, {"value": 666}, seq=1 << 30),
            ]
            results.append(await _refused_all("op", keys, to, origin, forged, failures))
            results.append(await _second_r1(keys, to, t1))
            node.set_input("value", 2)
            await until(lambda: node.outputs.get("value") == 2, 5.0)
            node.set_input("stop", True)
            await until(lambda: tree.root.state is State.SUCCEEDED, 5.0)
        ok = tree.root.state is State.SUCCEEDED and node.assignments == ["r1"] and not failures
        figures = {
            "state": tree.root.state.name,
            "assignments": list(node.assignments),
            "false_failures": failures,
            "outputs": dict(node.outputs),
        }
        results.append(("roles_mission", ok, figures))
    return results


async def _refused_all(
    who: str,
    keys: Path,
    target: ZmqTransport,
    agent: Agent,
    msgs: list[Message],
    failures: list[str],
) -> Result:
    """``who`` sends each message to ``target``'s actors; all must be refused by role."""
    before = target.stats.by_reason.get(_REFUSED, 0)
    paths = {Tick: "root", CallForBids: "mission", Award: "mission"}
    async with _serving(_transport(who, keys)) as attacker:
        attacker.add_peer(target.system_id, target.endpoint)
        for msg in msgs:
            path = paths.get(type(msg), "mission")
            if isinstance(msg, Heartbeat):
                path = "team"
            _send(attacker, Address(target.system_id, path), msg)
        done = await until(
            lambda: target.stats.by_reason.get(_REFUSED, 0) - before >= len(msgs), 5.0
        )
    refused = target.stats.by_reason.get(_REFUSED, 0) - before
    member = who in agent.team.members
    hosted = len(agent.mission_control.host.hosted)
    ok = done and refused == len(msgs) and not member and not failures
    name = {"eye": "observer_key_drives", "op+x": "observer_id_drives", "op": "operator_executes"}
    role = target.role_of(who)
    figures = {
        "role": role,
        "sent": len(msgs),
        "refused": refused,
        "member": member,
        "hosted": hosted,
    }
    return name[who], ok, figures


async def _second_r1(keys: Path, origin: ZmqTransport, r1: ZmqTransport) -> Result:
    """A second process with r1's own key says hello to the origin from elsewhere."""
    twin = _transport("r1", keys)
    twin.limit(role_table())
    twin.add_peer("origin", origin.endpoint)
    _send(twin, Address("origin", "team"), Heartbeat("r1", 1, 0))
    told = ""
    try:
        await asyncio.wait_for(twin.serve(lambda _e: None, task_status=_Ignored()), 5.0)
    except NameTaken as exc:
        told = str(exc)
    except TimeoutError:
        pass
    finally:
        twin.close()
    kept = origin.endpoint_of("r1") == r1.endpoint
    ok = "already live" in told and kept
    return "second_live_r1", ok, {"told": told[:120], "origin_kept_r1": kept}
