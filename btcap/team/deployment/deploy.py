"""Robots started from configuration files: an agent that serves until stopped, an
observer that looks at the team, and an operator that runs a mission tree.

The ``btcap agent``, ``btcap team status`` and ``btcap mission run`` commands are thin
wrappers around these, so programs can do the same inside their own event loop.
"""

from __future__ import annotations

import time
from collections.abc import AsyncIterator, Callable, Iterable
from contextlib import asynccontextmanager
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Any

import anyio

from btcap.actors import Address, Clock
from btcap.bt.files import load_tree
from btcap.bt.registry import NodeRegistry
from btcap.bt.state import DONE, State
from btcap.bt.tree import Tree
from btcap.errors import BtcapError
from btcap.team.capabilities.capability import Capability
from btcap.team.capabilities.capfiles import FileBid
from btcap.team.core.effects import Lost
from btcap.team.deployment.agentconfig import RobotConfig
from btcap.team.membership.membership import Membership
from btcap.team.messages import Activity, ActivityQuery
from btcap.team.runtime.agent import Agent

__all__ = [
    "CapabilityResult",
    "MemberView",
    "MissionReport",
    "observe_team",
    "open_agent",
    "run_mission_file",
    "wait_for_team",
]


@asynccontextmanager
async def open_agent(
    config: RobotConfig,
    registry: NodeRegistry,
    *,
    robot: str | None = None,
    implementations: bool = True,
    ephemeral: bool = False,
    insecure: bool = False,
    missions: bool = False,
) -> AsyncIterator[Agent]:
    """The configured robot (with its plugin's implementations and actors), in the team
    while the block runs; it says goodbye on exit, so the team re-assigns its work at
    once. ``robot``/``ephemeral``/``implementations=False`` make a short-lived observer or
    operator from the same file; ``insecure`` allows a keyless bind other hosts can
    reach; ``missions``: it will hold mission trees (see :class:`Agent`)."""
    ros = _ros_side(config, robot or config.robot) if implementations else None
    if ros is not None:
        ros.register(registry)
        try:
            await ros.start()
        except BtcapError as exc:  # ROS missing, a namespace taken: one line, the field
            raise config.error("ros", str(exc)) from None
    try:
        async with _serving(
            config, registry, ros, robot, implementations, ephemeral, insecure, missions
        ) as agent:
            yield agent
    finally:
        if ros is not None:
            await ros.close()


def _ros_side(config: RobotConfig, robot: str) -> Any | None:
    """The ROS side of an agent whose file has a ``ros:`` block (btcap/ros/agent.py,
    through the ``btcap.ros`` entry point: nothing of it is imported otherwise)."""
    settings = config.spec.ros
    if settings is None:
        return None
    found = list(metadata.entry_points(group="btcap.ros", name="agent"))
    if not found:
        raise config.error("ros", "the ROS bridge (btcap.ros) is not installed with btcap")
    return found[0].load()(settings, robot)


@asynccontextmanager
async def _serving(
    config: RobotConfig,
    registry: NodeRegistry,
    ros: Any | None,
    robot: str | None,
    implementations: bool,
    ephemeral: bool,
    insecure: bool,
    missions: bool,
) -> AsyncIterator[Agent]:
    _, impls = config.load_capabilities(registry, implementations=implementations)
    if ros is not None:
        try:
            impls = ros.wrap(impls)
        except BtcapError as exc:  # a pose type that cannot work: one line, the file
            raise config.error("capabilities.implementations", str(exc)) from None
    else:
        for impl in impls:
            if isinstance(impl.bid, FileBid) and impl.bid.distance is not None:
                where = impl.bid.distance.where
                raise config.error(
                    "capabilities.implementations",
                    f"{where}: bid.distance_from reads the robot's pose over ROS 2: "
                    "the agent file needs a ros: block",
                )
    plugged = config.load_plugin(factory=implementations)
    messages = plugged.messages
    transport = config.transport(messages, robot=robot, ephemeral=ephemeral, insecure=insecure)
    agent = Agent(
        robot or config.robot,
        transport=transport,
        clock=Clock(config.spec.timing.speedup),
        implementations=[*impls, *plugged.implementations],
        config=config.agent_config(),
        registry=messages,
        actors=plugged.actors,
        missions=missions,
    )
    if ros is not None:
        ros.attach(agent.system)
    try:
        async with agent:
            yield agent
    finally:
        transport.close()


async def wait_for_team(agent: Agent, expect: Iterable[str], *, timeout_s: float) -> bool:
    """Until every robot in ``expect`` is a member whose capabilities are known and the
    view has been stable for three heartbeats, at most ``timeout_s`` (wall) seconds.
    Whether the expected robots all showed up."""
    wanted = set(expect)
    period = agent.config.heartbeat_s
    stable_since: float | None = None
    last: frozenset[str] = frozenset()
    with anyio.move_on_after(timeout_s):
        while True:
            members = frozenset(agent.team.members)
            known = members <= agent.repository.team.keys() and wanted <= members
            now = agent.clock.now()
            if not known or members != last:
                stable_since = None
            elif stable_since is None:
                stable_since = now
            elif now - stable_since >= 3 * period:
                return True
            last = members
            await agent.clock.sleep(period)
    return wanted <= set(agent.team.members)


@dataclass(frozen=True, slots=True)
class MemberView:
    """One teammate as an observer sees it."""

    robot: str
    #: Interface name -> identity; None while its repository has not arrived.
    capabilities: dict[str, str] | None
    #: Capabilities it has completed (for preconditions).
    succeeded: list[str]
    heartbeat_age_s: float
    #: What its body runs, then holds queued (``origin:node#n``); None if it did not say.
    running: list[str] | None = None


async def observe_team(agent: Agent, *, timeout_s: float = 1.0) -> list[MemberView]:
    """The team as ``agent`` sees it now (without itself), sorted by robot, with what each
    runs (asked of every member at once; one that does not answer in ``timeout_s`` shows
    None)."""
    now = agent.clock.now()
    members = sorted(agent.team.members.items())
    doing: dict[str, list[str]] = {}

    async def ask(robot: str) -> None:
        with anyio.move_on_after(timeout_s):
            reply = await agent.system.ask(Address(robot, Membership.PATH), ActivityQuery())
            if isinstance(reply, Activity) and reply.robot == robot:
                doing[robot] = [str(e) for e in reply.running] + [
                    f"{e} (queued)" for e in reply.queued
                ]

    async with anyio.create_task_group() as tg:
        for robot, _ in members:
            tg.start_soon(ask, robot)
    out = []
    for robot, member in members:
        state = agent.repository.team.get(robot)
        out.append(
            MemberView(
                robot,
                None if state is None else dict(state.interfaces),
                [] if state is None else list(state.succeeded),
                max(0.0, now - member.last_seen),
                doing.get(robot),
            )
        )
    return out


@dataclass(frozen=True, slots=True)
class CapabilityResult:
    path: str
    state: State
    #: Robots that ran it, in order (more than one when it was re-assigned).
    robots: list[str]
    outputs: dict[str, Any]


@dataclass(slots=True)
class MissionReport:
    state: State
    elapsed_s: float
    timed_out: bool = False
    capabilities: list[CapabilityResult] = field(default_factory=list)

    @property
    def succeeded(self) -> bool:
        return self.state is State.SUCCEEDED and not self.timed_out


async def run_mission_file(
    agent: Agent,
    path: str | Path,
    registry: NodeRegistry,
    *,
    timeout_s: float | None = None,
    progress: Callable[[str], None] | None = None,
    on_tree: Callable[[Tree], object] | None = None,
) -> MissionReport:
    """Load a mission tree (capability node types must be in ``registry``), tick it on
    ``agent`` until it ends or ``timeout_s`` wall seconds pass, telling ``progress`` each
    change of a capability's state or executor, and why work moved when its robot failed
    or left ("beta failed — re-auctioning Greet"), and ``on_tree`` the tree before it
    runs (e.g. a monitor's ``add_tree``)."""
    tree = agent.mission(load_tree(path, registry, clock=agent.clock))
    if on_tree is not None:
        on_tree(tree)
    caps = [n for n in tree.nodes() if isinstance(n, Capability)]
    paths = {n.path for n in caps}
    seen: dict[str, tuple[State, str]] = {}
    lost: dict[str, Lost] = {}
    started = time.monotonic()

    def report(root: State) -> bool:
        for node in caps:
            # Unassigned is on nobody, whoever had it last.
            on = node.assignments[-1] if node.assignments and node.state != _UNASSIGNED else ""
            now = (node.state, on)
            at = f"{time.monotonic() - started:7.2f} s  {node.path}:"
            if progress is not None and (e := lost.pop(node.path, None)) is not None:
                progress(f"{at} {_gone(e)} — re-auctioning {type(node).INTERFACE.name}")
                if now[0] is _UNASSIGNED:
                    seen[node.path] = now  # the line above says it, and why
            if progress is not None and seen.get(node.path) != now:
                robot = f" on {now[1]}" if now[1] else ""
                progress(f"{at} {now[0].value}{robot}")
            seen[node.path] = now
        return root in DONE

    def on_lost(e: Lost) -> None:
        if e.execution.origin == agent.robot and e.execution.node in paths:
            lost[e.execution.node] = e

    state = State.IDLE
    timed_out = False
    unwatch = agent.mission_control.watch_lost(on_lost)
    try:
        with anyio.move_on_after(timeout_s) as scope:
            state = await tree.run(agent.config.tick_hz, until=report)
        timed_out = scope.cancelled_caught
        report(state)
        results = [
            CapabilityResult(n.path, n.state, list(n.assignments), dict(n.outputs)) for n in caps
        ]
    finally:
        unwatch()
        await tree.shutdown()
    return MissionReport(state, time.monotonic() - started, timed_out, results)


_UNASSIGNED = State.UNASSIGNED


def _gone(e: Lost) -> str:
    """Why a capability's executor lost its run, from its side of the team."""
    robot = f"robot {e.executor} "
    if e.why.startswith(robot):  # "robot beta failed", "robot beta left"
        return e.why.removeprefix("robot ")
    if e.why == "lease lapsed":
        return f"{e.executor} stopped answering (its lease lapsed)"
    return f"lost on {e.executor} ({e.why})"
