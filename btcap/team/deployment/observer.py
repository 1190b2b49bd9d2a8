"""An observer: looks at a running team without joining it (``btcap team status``).

It runs under an id of its own, ``NAME+TAG`` (NAME the config's robot, whose key it
uses), so it never takes a live member's place, and it sends no heartbeats: it is never
a member, never counted, bid to, awarded work or asked to vouch. It asks each robot's
:class:`~btcap.team.membership.status.StatusDesk` once, starting from the seeds and
following the members they name.
"""

from __future__ import annotations

from collections.abc import AsyncIterator, Iterable
from contextlib import asynccontextmanager

import anyio

from btcap.actors import ActorError, ActorSystem, Address, Clock
from btcap.team.deployment.agentconfig import RobotConfig
from btcap.team.deployment.deploy import MemberView
from btcap.team.membership.roles import role_table
from btcap.team.membership.status import StatusDesk
from btcap.team.messages import StatusQuery, TeamStatus
from btcap.transports.identity import observer_id

__all__ = ["open_observer", "survey"]


@asynccontextmanager
async def open_observer(
    config: RobotConfig, *, member: str | None = None, tag: str = "status", insecure: bool = False
) -> AsyncIterator[ActorSystem]:
    """An actor system beside the configured robot (same host, a port of its own) that
    can ask the team, as ``ROBOT+TAG-xxxxxx`` (``member`` instead of the config's robot:
    with keys, the key must be that member's), with the config's keys if any."""
    messages = config.load_plugin(factory=False).messages
    robot = observer_id(member or config.robot, tag)
    transport = config.transport(messages, robot=robot, ephemeral=True, insecure=insecure)
    transport.limit(role_table())
    system = ActorSystem(robot, transport=transport, registry=messages, clock=Clock())
    try:
        async with system:
            yield system
    finally:
        transport.close()


async def survey(
    system: ActorSystem, seeds: Iterable[str], *, timeout_s: float, ask_s: float = 1.0
) -> tuple[bool, list[MemberView]]:
    """Ask the seeds, then every member they name, how they see the team, for at most
    ``timeout_s`` seconds. Whether every seed and every member named answered, and the
    members (sorted; a heartbeat's age is the freshest any teammate saw)."""
    answers: dict[str, TeamStatus] = {}
    wanted = list(dict.fromkeys(seeds))
    transport = system.transport

    async def ask(robot: str) -> None:
        try:
            with anyio.move_on_after(ask_s):
                reply = await system.ask(Address(robot, StatusDesk.PATH), StatusQuery())
                if isinstance(reply, TeamStatus) and reply.robot == robot:
                    answers[robot] = reply
        except ActorError:  # not a robot of this version, or gone: it shows as missing
            pass

    with anyio.move_on_after(timeout_s):
        while True:
            named: dict[str, str] = {}
            for status in answers.values():
                for seen in status.members:
                    named.setdefault(seen.robot, seen.endpoint)
            missing = [r for r in dict.fromkeys([*wanted, *named]) if r not in answers]
            if not missing:
                break
            for robot in missing:
                endpoint = named.get(robot)
                if transport is not None and endpoint:
                    transport.introduce(robot, endpoint)
            async with anyio.create_task_group() as tg:
                for robot in missing:
                    tg.start_soon(ask, robot)
            if any(r not in answers for r in missing):
                await anyio.sleep(0.1)
    return _views(answers, wanted)


def _views(answers: dict[str, TeamStatus], wanted: list[str]) -> tuple[bool, list[MemberView]]:
    ages: dict[str, float] = {}
    named: set[str] = set()
    for status in answers.values():
        for seen in status.members:
            named.add(seen.robot)
            age = seen.heartbeat_age_ms / 1000
            ages[seen.robot] = min(age, ages.get(seen.robot, age))
    views = []
    for robot in sorted(set(answers) | named):
        said = answers.get(robot)
        views.append(
            MemberView(
                robot,
                None if said is None else dict(said.interfaces),
                [] if said is None else list(said.succeeded),
                ages.get(robot, 0.0),
                None
                if said is None
                else [str(e) for e in said.running] + [f"{e} (queued)" for e in said.queued],
            )
        )
    complete = all(r in answers for r in [*wanted, *named])
    return complete, views
