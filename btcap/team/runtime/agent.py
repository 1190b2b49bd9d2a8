"""The per-robot runtime: one actor system with membership, repository, the allocation
strategy's actor (the auctioneer, or consensus), mission control and a host tree with a
remote capability slot."""

from __future__ import annotations

import asyncio
import concurrent.futures.thread  # noqa: F401  asyncio.to_thread's pool, loaded before joining
import contextlib
import importlib
import sys
import weakref
from collections.abc import Iterable, Mapping
from types import TracebackType
from typing import Any

from btcap.actors import Actor, ActorSystem, SystemClosed, TimeSource
from btcap.actors.loops import report_stalls
from btcap.bt.node import Node
from btcap.bt.state import DONE, State
from btcap.bt.tree import Tree
from btcap.team.allocation.strategies import resolve
from btcap.team.allocation.strategy import Allocator, Strategy
from btcap.team.capabilities.capability import ASSIGNER
from btcap.team.capabilities.implementation import Implementation
from btcap.team.capabilities.slot import SLOT_HOST, RemoteCapabilitySlot
from btcap.team.ids import ExecutionId
from btcap.team.membership.departures import DepartureLog
from btcap.team.membership.membership import Membership, TeamEvent
from btcap.team.membership.repository import CapabilityRepository
from btcap.team.membership.roles import role_table
from btcap.team.membership.status import StatusDesk
from btcap.team.runtime.mission import MissionControl
from btcap.team.runtime.protocol import protocol_registry
from btcap.team.settings import AgentConfig
from btcap.transports import MessageRegistry, Transport
from btcap.transports.identity import check_member_name

__all__ = ["Agent", "AgentConfig"]


class Agent:
    """Everything one robot runs; use as ``async with Agent("husky1", ...) as agent``.

    ``actors`` are spawned beside the runtime's own (e.g. a simulated robot's body).
    ``host`` is the robot's own tree; by default just a :class:`RemoteCapabilitySlot`,
    ticked at ``config.tick_hz`` while the agent runs. Give your own host tree that
    contains a slot to do other work beside it. ``strategy`` allocates the tasks of
    this robot's capability nodes: a registered name (:mod:`btcap.team.allocation.strategies`) or a
    :class:`~btcap.team.allocation.strategy.Strategy` object; by default ``config.strategy``.

    Nothing may hold the robot's event loop for long (its heartbeats would stop and its
    team declare it failed): the agent imports in a worker thread what its strategy loads
    on first use (``Strategy.modules``: numpy and scipy for the planning strategies, 0.7
    to 2.5 s), as it starts (before joining) when ``missions`` says it will hold mission
    trees (an operator), else when a mission tree is first attached, so its first batch of
    auctions, planned in a worker thread too, does not wait for them. A robot that only
    runs others' work never imports them. In asyncio's debug
    mode (``python -X dev``) a callback that holds the loop longer than 50 ms is reported
    (:func:`btcap.actors.loops.report_stalls`).
    """

    def __init__(
        self,
        robot: str,
        *,
        transport: Transport | None = None,
        clock: TimeSource | None = None,
        implementations: Iterable[Implementation] = (),
        config: AgentConfig | None = None,
        host: Node | None = None,
        registry: MessageRegistry | None = None,
        actors: Mapping[str, Actor] | None = None,
        strategy: str | Strategy | None = None,
        missions: bool = False,
    ) -> None:
        if (why := check_member_name(robot)) is not None:
            raise ValueError(f"robot {robot!r}: {why}")
        self.robot = robot
        self.config = config or AgentConfig()
        reg = registry or protocol_registry()
        if transport is not None:  # what each role may send (btcap.team.membership.roles)
            transport.limit(role_table())
        self.system = ActorSystem(robot, transport=transport, registry=reg, clock=clock)
        cfg = self.config
        self.team = Membership(
            robot,
            heartbeat_s=cfg.heartbeat_s,
            failure_timeout_s=cfg.failure_timeout_s,
            fanout=cfg.heartbeat_fanout,
            repo_version=lambda: self.repository.version,
            busy=lambda: not self.mission_control.body.idle,
            activity=self._activity,
        )
        if transport is not None:  # a non-member's messages are held to a smaller size
            transport.members(lambda peer: peer in self.team.table.members)
        #: Who failed or left lately (for ``btcap team status``).
        self.departures = DepartureLog(self.team)
        self.repository = CapabilityRepository(robot, team=self.team)
        self.repository.extend(implementations)
        self.status_desk = StatusDesk(self.team, self.repository, self._activity)
        self.strategy = resolve(cfg.strategy if strategy is None else strategy)
        self.mission_control = MissionControl(
            robot, self.repository, self.team, self.strategy, config=cfg
        )
        #: This robot's part of the strategy (the auctioneer, or consensus).
        self.allocator: Allocator = self.mission_control.allocator
        self.host = Tree(
            host or RemoteCapabilitySlot(), name=f"{robot}-host", clock=self.system.clock
        )
        self._host_task: asyncio.Task[Any] | None = None
        self._extra = dict(actors or {})
        self._missions: weakref.WeakSet[Tree] = weakref.WeakSet()
        self._importing = False  # the strategy's modules (see the class)
        self._missions_ahead = missions

    def _on_team(self, event: TeamEvent, robot: str) -> None:
        """A teammate declared failed or gone costs nothing more: the transport stops
        dialling it, closes its sockets and drops what was queued for it (it is dialled
        back if it speaks again)."""
        transport = self.system.transport
        if transport is not None and event in (TeamEvent.FAILED, TeamEvent.LEFT):
            transport.forget(robot)

    @property
    def clock(self) -> TimeSource:
        return self.system.clock

    def _activity(self) -> tuple[list[ExecutionId], list[ExecutionId]]:
        body = self.mission_control.body
        return [e for e in (body.running,) if e], [e for e in (body.queued,) if e]

    async def __aenter__(self) -> Agent:
        report_stalls(asyncio.get_running_loop())  # in asyncio's debug mode
        await self.system.__aenter__()
        try:
            if self._missions_ahead:  # before joining: its first auctions need them
                self._import_strategy_modules()
            s = self.system
            s.spawn(self.team, Membership.PATH)
            s.spawn(self.departures, DepartureLog.PATH)
            s.spawn(self.repository, CapabilityRepository.PATH)
            s.spawn(self.status_desk, StatusDesk.PATH)
            s.spawn(self.allocator, self.allocator.PATH)
            s.spawn(self.mission_control, MissionControl.PATH)
            s.services.provide(ASSIGNER, self.mission_control)  # to capability nodes
            s.services.provide(SLOT_HOST, self.mission_control)  # to the remote slot
            for path, actor in self._extra.items():
                s.spawn(actor, path)
            self.team.subscribe(self._on_team)  # last: the others hear a loss first
            self.host.attach(s)
            self.host.setup()
            self._host_task = s.start_task(self._run_host(), name=f"host tree {self.robot}")
        except BaseException as exc:
            await self.system.__aexit__(type(exc), exc, exc.__traceback__)
            raise
        return self

    async def _run_host(self) -> None:
        await self.host.run(self.config.tick_hz, until=lambda _s: False)

    async def __aexit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> bool | None:
        if self._host_task is not None:
            self._host_task.cancel()
        for tree in list(self._missions):  # the robot leaves: its missions end with it
            await tree.shutdown()
        await self.host.shutdown()
        return await self.system.__aexit__(exc_type, exc, tb)

    def mission(self, root: Node | Tree, *, name: str | None = None) -> Tree:
        """Attach a mission tree to this robot so its capability nodes can be assigned.

        A mission tree still attached when the agent exits is shut down with it.
        """
        tree = root if isinstance(root, Tree) else Tree(root, name=name, clock=self.clock)
        self._import_strategy_modules()
        tree.clock = self.clock
        tree.attach(self.system)
        self._missions.add(tree)
        return tree

    def _import_strategy_modules(self) -> None:
        """Import the strategy's heavy modules in a worker thread, once (see the class)."""
        cold = [m for m in getattr(self.strategy, "modules", ()) if m not in sys.modules]
        if cold and not self._importing:  # for this robot's auctions, off the loop
            with contextlib.suppress(SystemClosed):  # not started: its first plan imports them
                work = asyncio.to_thread(_import, cold)
                self.system.start_task(work, name=f"{self.robot} imports")
                self._importing = True

    async def run_mission(
        self, root: Node | Tree, *, rate_hz: float | None = None, max_ticks: int | None = None
    ) -> State:
        """Attach and tick a mission tree until it succeeds or fails.

        At ``max_ticks`` the tree is halted and :class:`~btcap.bt.state.TreeTimeout` raised.
        """
        tree = self.mission(root)
        try:
            return await tree.run(
                rate_hz or self.config.tick_hz, max_ticks=max_ticks, until=lambda s: s in DONE
            )
        finally:
            await tree.shutdown()


def _import(modules: list[str]) -> None:
    """Import ``modules`` (in a worker thread: see :class:`Agent`)."""
    for name in modules:
        importlib.import_module(name)
