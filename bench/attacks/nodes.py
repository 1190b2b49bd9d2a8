"""Node-action attacks: another actor system drives a robot's behavior-tree nodes.

Every BT node is an actor at a predictable path (``tree:<name>/...``) with Setup, Tick,
Untick, Reset and Shutdown handlers. A team of two agents, ``origin`` and ``r1`` (which
hosts the origin's Echo run), and an attacker system ``mallory`` on the same network:
in-process, keyless tcp, or CURVE over tcp with a key the team trusts (a member's key).
For each attack a fresh mission starts; once its run is RUNNING on r1, mallory asks a
node action at a node's path (:data:`REPEAT` times), the team goes on for
:data:`OBSERVE_S`, then the origin stops the echo the legitimate way.

An attack *succeeds* if a node obeyed (replied with its status) or the mission came to
harm: it ended before the origin stopped it, its run started over (the echo's tick count
fell), a tick raised, the work moved to another robot, or it did not end SUCCEEDED with
the last value. :func:`probe` returns one ``(name, passed, figures)`` per attack and
team; it passes when the attack did not succeed, every attempt was refused with a
``Refused`` failure and the target's runtime counted each of them.
"""

from __future__ import annotations

import asyncio
import contextlib
import tempfile
import time
from collections.abc import AsyncIterator, Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from btcap import ReactiveSequence as SequenceNode
from btcap.actors import ActorFailed, ActorSystem, Message
from btcap.bt.messages import NodeStatus, Reset, Shutdown, Tick
from btcap.bt.node import Node
from btcap.bt.state import DONE, State
from btcap.bt.tree import Tree
from btcap.team.capabilities.capability import Capability
from btcap.team.demo import ECHO, EchoLeaf, implementations
from btcap.team.runtime.agent import Agent, AgentConfig
from btcap.team.runtime.protocol import protocol_registry
from btcap.transports import InProcessNetwork, KeyPair, TeamKeys, Transport, ZmqTransport
from btcap.transports.security import write_key_pair

__all__ = ["ATTACKS", "MODES", "NodeAttack", "Outcome", "Scene", "node_team", "probe", "strike"]

ATTACKER = "mallory"
#: How the three systems reach each other: in-process, keyless tcp, CURVE tcp.
MODES = ("inprocess", "tcp", "curve")
_TCP = "tcp://127.0.0.1:*"
TICK_S = 0.01
REPEAT = 3  # attempts per attack: refused and counted each time, logged once
OBSERVE_S = 0.3  # how long the team goes on after an attack before the origin stops it
ASK_S = 2.0
TEAM_CONFIG = AgentConfig(
    heartbeat_s=0.1, failure_timeout_s=3.0, lease_s=3.0, keepalive_s=0.5, tick_hz=50.0
)
WARM_TICKS = 3  # the run has ticked this often before an attack (a restart shows)


@dataclass
class Scene:
    """One mission of the origin, its run hosted on r1, and the attacker."""

    origin: Agent
    r1: Agent
    mallory: ActorSystem
    tree: Tree
    node: Capability
    run: Tree  # the hosted run's tree on r1

    def leaf(self) -> Node:
        return next(n for n in self.run.nodes() if isinstance(n, EchoLeaf))


@dataclass(frozen=True)
class NodeAttack:
    """A node action ``msg`` that mallory sends to the node ``where`` picks."""

    name: str
    msg: Message
    where: Callable[[Scene], Node]


#: The five attacks of issue 19 that a member key got through before node actions were
#: local-only: each one a node action at a node of another robot's tree.
ATTACKS = (
    NodeAttack("tick_stop_mission_node", Tick({"stop": True}), lambda s: s.node),
    NodeAttack("shutdown_hosted_leaf", Shutdown(), lambda s: s.leaf()),
    NodeAttack("reset_hosted_root", Reset(), lambda s: s.run.root),
    NodeAttack("shutdown_mission_root", Shutdown(), lambda s: s.tree.root),
    NodeAttack("reset_mission_root", Reset(), lambda s: s.tree.root),
)


@dataclass
class Outcome:
    """What one attack did; :attr:`succeeded` is the verdict."""

    attack: str
    target: str = ""
    obeyed: int = 0  # replies with a node status
    refused: int = 0  # Refused failures
    other_errors: list[str] = field(default_factory=list)
    counted: int = 0  # the target runtime's refusal counter, moved by this attack
    ended_early: str | None = None  # the mission's state if it ended before the stop
    restarted: bool = False
    tick_errors: int = 0
    final: str = ""
    assignments: list[str] = field(default_factory=list)
    value: Any = None

    @property
    def harmed(self) -> bool:
        return (
            self.ended_early is not None
            or self.restarted
            or self.tick_errors > 0
            or self.final != State.SUCCEEDED.name
            or self.assignments != ["r1"]
        )

    @property
    def succeeded(self) -> bool:
        return self.obeyed > 0 or self.harmed

    @property
    def passed(self) -> bool:
        return not self.succeeded and self.refused == REPEAT and self.counted == REPEAT


# -- the team -------------------------------------------------------------------------------


@contextlib.contextmanager
def _key_folder() -> Iterator[Path | None]:
    with tempfile.TemporaryDirectory(prefix="btcap-nodes-") as tmp:
        folder = Path(tmp)
        team = folder / "team"
        team.mkdir()
        for name in ("origin", "r1", ATTACKER):
            public, _ = write_key_pair(folder, name)
            (team / public.name).write_bytes(public.read_bytes())
        yield folder


def _zmq(name: str, keys: Path | None, peers: dict[str, str]) -> ZmqTransport:
    return ZmqTransport(
        name,
        _TCP,
        protocol_registry(),
        peers=peers,
        keys=None if keys is None else KeyPair.load(keys / f"{name}.key_secret"),
        trusted=None if keys is None else TeamKeys.load(keys / "team"),
    )


@contextlib.asynccontextmanager
async def node_team(mode: str) -> AsyncIterator[tuple[Agent, Agent, ActorSystem]]:
    """``origin``, ``r1`` (an Echo provider) and the attacker, running, in ``mode``."""
    if mode not in MODES:
        raise ValueError(f"mode {mode!r}: expected one of {', '.join(MODES)}")
    with _key_folder() if mode == "curve" else contextlib.nullcontext() as keys:
        transports: dict[str, Transport]
        if mode == "inprocess":
            net = InProcessNetwork(protocol_registry())
            transports = {n: net.transport(n) for n in ("r1", "origin", ATTACKER)}
        else:
            t1 = _zmq("r1", keys, {})
            to = _zmq("origin", keys, {"r1": t1.endpoint})
            tm = _zmq(ATTACKER, keys, {"r1": t1.endpoint, "origin": to.endpoint})
            transports = {"r1": t1, "origin": to, ATTACKER: tm}
        r1 = Agent(
            "r1",
            transport=transports["r1"],
            implementations=implementations("r1"),
            config=TEAM_CONFIG,
        )
        origin = Agent("origin", transport=transports["origin"], config=TEAM_CONFIG)
        mallory = ActorSystem(transport=transports[ATTACKER], registry=protocol_registry())
        async with r1, origin, mallory:
            await _until(lambda: "r1" in origin.repository.providers(ECHO.identity), 10.0)
            yield origin, r1, mallory


async def _until(cond: Callable[[], bool], timeout: float) -> None:
    deadline = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > deadline:
            raise TimeoutError("the team did not get there in time")
        await asyncio.sleep(TICK_S)


# -- one attack -------------------------------------------------------------------------------


@dataclass
class _Watch:
    """What the origin's ticks saw."""

    ticks: list[int] = field(default_factory=list)
    errors: int = 0
    ended: State | None = None
    stopped: bool = False  # the origin has stopped the echo itself


async def _tick(tree: Tree, node: Capability, watch: _Watch, stop: asyncio.Event) -> None:
    while not stop.is_set():
        try:
            state = tree.tick()
        except Exception:
            watch.errors += 1
        else:
            if state in DONE and not watch.stopped and watch.ended is None:
                watch.ended = state
            n = node.outputs.get("ticks")
            if isinstance(n, int):
                watch.ticks.append(n)
        await asyncio.sleep(TICK_S)


async def _send(scene: Scene, attack: NodeAttack, out: Outcome) -> None:
    target = attack.where(scene).address
    out.target = str(target)
    for _ in range(REPEAT):
        try:
            reply = await scene.mallory.ask(target, attack.msg, timeout=ASK_S)
        except ActorFailed as exc:
            if exc.error_type == "Refused":
                out.refused += 1
            else:
                out.other_errors.append(f"{exc.error_type}: {exc.detail}"[:200])
        except Exception as exc:
            out.other_errors.append(f"{type(exc).__name__}: {exc}"[:200])
        else:
            if isinstance(reply, NodeStatus):
                out.obeyed += 1


def _ticks(node: Capability) -> int:
    n = node.outputs.get("ticks")
    return n if isinstance(n, int) else 0


def _refusals(agent: Agent) -> int:
    return sum(agent.system.stats.refused.values())


async def strike(origin: Agent, r1: Agent, mallory: ActorSystem, attack: NodeAttack) -> Outcome:
    """Run one attack against a fresh mission of ``origin`` and see what it did."""
    out = Outcome(attack.name)
    node = ECHO.node_type()("echo", inputs={"value": 1})
    assert isinstance(node, Capability)
    tree = origin.mission(SequenceNode("root", children=[node]), name=attack.name)
    watch, stop = _Watch(), asyncio.Event()
    ticker = asyncio.create_task(_tick(tree, node, watch, stop))
    try:
        await _until(lambda: _ticks(node) >= WARM_TICKS and node.outputs["value"] == 1, 10.0)
        assert node.execution is not None
        hosted = r1.mission_control.host.hosted[node.execution.id]
        scene = Scene(origin, r1, mallory, tree, node, hosted.run.tree)
        target = origin if attack.where(scene).tree is tree else r1
        before = _refusals(target)
        await _send(scene, attack, out)
        await asyncio.sleep(OBSERVE_S)
        out.counted = _refusals(target) - before
        node.set_input("value", 2)
        with contextlib.suppress(TimeoutError):
            await _until(lambda: node.outputs["value"] == 2 or watch.ended is not None, 3.0)
        watch.stopped = True
        node.set_input("stop", True)
        with contextlib.suppress(TimeoutError):
            await _until(lambda: tree.root.state in DONE, 3.0)
    except TimeoutError:
        pass
    finally:
        stop.set()
        await asyncio.gather(ticker, return_exceptions=True)
        out.ended_early = watch.ended.name if watch.ended is not None else None
        out.restarted = any(b < a for a, b in zip(watch.ticks, watch.ticks[1:], strict=False))
        out.tick_errors = watch.errors
        out.final = tree.root.state.name
        out.assignments = list(node.assignments)
        out.value = node.outputs.get("value")
        if out.value != 2 and out.final == State.SUCCEEDED.name:
            out.final = f"{out.final} with value {out.value!r}"
        with contextlib.suppress(Exception):
            await tree.shutdown()
    return out


async def probe(
    quick: bool, modes: tuple[str, ...] = ("tcp", "curve")
) -> list[tuple[str, bool, dict[str, Any]]]:
    """Every attack in every mode: ``(check name, passed, figures)``."""
    del quick  # each attack is a handful of messages: the same in both forms
    checks: list[tuple[str, bool, dict[str, Any]]] = []
    for mode in modes:
        async with node_team(mode) as (origin, r1, mallory):
            for attack in ATTACKS:
                out = await strike(origin, r1, mallory, attack)
                figures = {
                    "succeeded": out.succeeded,
                    "obeyed": out.obeyed,
                    "refused": out.refused,
                    "counted": out.counted,
                    "target": out.target,
                    "ended_early": out.ended_early,
                    "restarted": out.restarted,
                    "tick_errors": out.tick_errors,
                    "final": out.final,
                    "assignments": out.assignments,
                }
                if out.other_errors:
                    figures["other_errors"] = out.other_errors
                checks.append((f"node_{mode}_{attack.name}", out.passed, figures))
    return checks
