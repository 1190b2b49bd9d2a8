"""The live monitor: attach it to your robots' agents and trees, open its page.

::

    async with Monitor(port=8765, record="run.jsonl") as monitor:
        monitor.add_agent(agent)            # its host tree, team view and auctions
        monitor.add_tree(mission, robot=agent.robot)
        ...                                 # http://127.0.0.1:8765/
        monitor.finish("succeeded", "mission succeeded after 12 s")  # else "stopped"

Changes are collected as they happen and handed on in batches, at most ``batch_hz``
times a second (wall time), to the picture (:class:`~btcap.monitor.view.TeamView`), the
recording and every connected page. The page is read-only: it cannot change a robot.
On a virtual clock (:meth:`Monitor.follow`) batches fall every so many seconds of that
clock instead, so the recording of a deterministic run is the same byte for byte.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Any

from btcap.actors import TimeSource
from btcap.bt.tree import Tree
from btcap.monitor.hub import Hub
from btcap.monitor.net import is_loopback
from btcap.monitor.pacing import Pacer
from btcap.monitor.record import open_recorder
from btcap.monitor.taps import TreeTap
from btcap.monitor.view import Event, TeamView
from btcap.team.allocation.auction import Assigned, AuctionRecord
from btcap.team.core.effects import Lost
from btcap.team.membership.membership import TeamEvent
from btcap.team.runtime.agent import Agent
from btcap.transports.log import get_logger

if TYPE_CHECKING:
    from btcap.monitor.foxlive import FoxgloveLive
    from btcap.monitor.server import MonitorServer

__all__ = ["FOLLOW_EVERY_S", "RESULTS", "Monitor"]

log = get_logger(__name__)

#: Reasons of lost executions kept for the runs they end.
_MAX_LOST = 1000
#: How a run can end (:meth:`Monitor.finish`).
RESULTS = ("succeeded", "failed", "stopped")
_STATUS = {TeamEvent.JOINED: "joined", TeamEvent.LEFT: "left", TeamEvent.FAILED: "failed"}
#: Clock seconds between batches on a virtual clock (:meth:`Monitor.follow`): the
#: simulator's step, so a replay misses no cell of a drive and a long run stays cheap.
FOLLOW_EVERY_S = 0.5


class Monitor:
    """Watches robots' trees, membership and auctions; serves and/or records them.

    ``port`` None serves nothing (record only); 0 picks a free port (see :attr:`url`).
    ``host`` is loopback unless you say otherwise: the page shows your whole team.
    ``record`` ending ``.mcap`` records MCAP for Foxglove, anything else JSON Lines;
    ``metadata`` (scenario, seed, settings ...) is written at the recording's start.
    ``foxglove`` ``(host, port)`` serves the recording's channels live over the Foxglove
    WebSocket protocol (:mod:`btcap.monitor.foxlive`; the ``foxglove-sdk`` package).
    """

    def __init__(
        self,
        *,
        host: str = "127.0.0.1",
        port: int | None = 0,
        record: str | Path | None = None,
        batch_hz: float = 20.0,
        title: str = "btcap team",
        viewpoint: str | None = None,
        metadata: Mapping[str, str] | None = None,
        foxglove: tuple[str, int] | None = None,
    ) -> None:
        if not 0 < batch_hz <= 20:
            raise ValueError(f"batch_hz {batch_hz}: expected a rate in (0, 20] per second")
        self.view = TeamView()
        self.batch_s = 1.0 / batch_hz
        self.title = title
        self.viewpoint = viewpoint
        self._hub = Hub()
        self._address = (host, port)
        self._server: MonitorServer | None = None
        self._foxglove = foxglove
        self._live: FoxgloveLive | None = None
        self._sources: list[Callable[[], Event | None]] = []
        self._recorder = open_recorder(Path(record), metadata) if record is not None else None
        self._pending: list[Event] = []
        self._taps: list[TreeTap] = []
        self._status: dict[str, str] = {}
        self._last_join: tuple[float, str] | None = None
        self._lost: dict[str, str] = {}  # execution -> why it was lost
        self._ended: dict[str, tuple[str, str | None]] = {}  # node -> (result, why)
        self._hosting: set[str] = set()  # executions whose start a slot reported
        self._asked: dict[str, float] = {}  # node -> when its last auction opened
        self._detach: list[Callable[[], None]] = []
        self._pacer = Pacer(self._safe_flush, self.batch_s)
        self._finished = False
        if port is not None and not is_loopback(host):
            log.warning("monitor.public", host=host, note="anyone who can reach it sees the team")
        if foxglove is not None and not is_loopback(foxglove[0]):
            log.warning("monitor.public", host=foxglove[0], note="Foxglove: anyone sees the team")

    # -- life cycle -------------------------------------------------------------------
    async def start(self) -> None:
        host, port = self._address
        if port is not None:
            from btcap.monitor.server import MonitorServer  # aiohttp only when serving

            self._server = MonitorServer(self, host, port)
            try:
                await self._server.start()
            except BaseException:
                self._server = None
                if self._recorder is not None:
                    self._recorder.close()  # nobody calls stop() after a failed start
                raise
        if self._foxglove is not None:
            from btcap.monitor.foxlive import FoxgloveLive  # the SDK only when serving it

            try:
                self._live = FoxgloveLive(*self._foxglove)
            except BaseException:
                if self._server is not None:
                    await self._server.stop()
                if self._recorder is not None:
                    self._recorder.close()
                raise
        self._pacer.pace(None, FOLLOW_EVERY_S)

    def follow(self, clock: TimeSource, *, every_s: float = FOLLOW_EVERY_S) -> None:
        """Batch every ``every_s`` seconds of ``clock`` if it is virtual (an infinite
        speed-up: :class:`~btcap.actors.ManualClock`), until :meth:`detach`: the states
        a batch samples then depend on the run alone, not on how fast the machine computed
        it, and two runs of a deterministic simulation record the same bytes. A clock
        that keeps pace with the wall changes nothing (batches stay on wall time)."""
        if not every_s > 0:
            raise ValueError(f"every_s {every_s}: expected clock seconds > 0")
        if not self._pacer.started:
            raise RuntimeError("start the monitor before it follows a clock")
        if math.isinf(clock.speedup):
            self.flush()  # what wall time collected so far: before the clock's batches
            self._pacer.pace(clock, every_s)

    def detach(self) -> None:
        """Stop watching (the picture and the page stay, e.g. a finished mission's last
        states rather than its shutdown); a followed clock is let go (see :meth:`follow`)."""
        for detach in reversed(self._detach):
            detach()
        self._detach.clear()
        self.flush()
        if self._pacer.following is not None and self._pacer.started:
            self._pacer.pace(None, FOLLOW_EVERY_S)

    def finish(self, result: str, summary: str) -> None:
        """Say the run is over and hand it on at once, after the changes before it:
        ``result`` is ``succeeded``, ``failed`` or ``stopped``, ``summary`` one line for a
        person ("mission succeeded after 1337 s"). Pages show it and keep the final
        picture when the monitor stops; it is recorded, so a replay's end shows it too.
        :meth:`stop` says ``stopped`` if nobody said how the run ended."""
        if result not in RESULTS:
            raise ValueError(f"result {result!r}: expected one of {', '.join(RESULTS)}")
        self.flush()
        self._finished = True
        self.emit({"t": self.view.t, "k": "finished", "result": result, "summary": summary})
        self.flush()

    async def stop(self) -> None:
        """Detach from everything, hand on the last changes and how the run ended (see
        :meth:`finish`), close the pages (they keep the final picture) and the file."""
        self.detach()
        await self._pacer.stop()
        self.flush()
        if not self._finished:
            self.finish("stopped", "monitoring stopped")
        if self._server is not None:
            await self._server.stop()
        if self._recorder is not None:
            self._recorder.close()
        if self._live is not None:
            self._live.close()

    async def __aenter__(self) -> Monitor:
        await self.start()
        return self

    async def __aexit__(
        self, et: type[BaseException] | None, e: BaseException | None, tb: TracebackType | None
    ) -> None:
        await self.stop()

    @property
    def live(self) -> FoxgloveLive:
        """The Foxglove server (after :meth:`start`): its ``port``, its subscriptions."""
        if self._live is None:
            raise RuntimeError("this monitor serves no Foxglove channels (foxglove=None)")
        return self._live

    @property
    def url(self) -> str:
        """Where the page is served (after :meth:`start`)."""
        if self._server is None:
            raise RuntimeError("this monitor serves no page (port=None, or not started)")
        return self._server.url

    # -- what it watches --------------------------------------------------------------
    def add_tree(self, tree: Tree, *, robot: str) -> Callable[[], None]:
        """Show ``tree`` as one of ``robot``'s trees; returns a detach (state kept)."""
        self._robot(robot, tree.clock.now())
        names = {t.name for t in self._taps if t.robot == robot}
        name, k = tree.name, 1
        while name in names:
            k += 1
            name = f"{tree.name}~{k}"
        tap = TreeTap(tree, robot, name, self._emit_run, self._run_ended, self._emit_hosted)
        self._taps.append(tap)
        self.emit(tap.structure())

        def detach() -> None:
            if tap in self._taps:
                self._flush_tap(tap)
                tap.close()
                self._taps.remove(tap)

        self._detach.append(detach)
        return detach

    def add_agent(self, agent: Agent) -> Callable[[], None]:
        """Show a robot: its host tree (with the capability runs it hosts), the auctions
        it holds and why its capabilities lost their executors. Membership is as the
        ``viewpoint`` robot sees it (by default the first agent added). Add its mission
        trees with :meth:`add_tree`. Returns a detach."""
        robot, now, clock = agent.robot, agent.clock.now(), agent.clock
        self._robot(robot, now)
        undo = [
            self.add_tree(agent.host, robot=robot),
            agent.mission_control.watch_lost(self._on_lost),
            agent.allocator.watch(self._on_auction),  # auctions, or consensus allocations
        ]
        if self.viewpoint is None:
            self.viewpoint = robot
        if robot == self.viewpoint:  # robots may disagree (one cut off sees all others fail)
            for member in sorted(agent.team.alive()):  # itself, and who joined before
                self._team(member, "joined", now)
            undo.append(agent.team.subscribe(lambda ev, who: self._on_team(ev, who, clock.now())))

        def detach() -> None:
            for u in undo:
                u()

        self._detach.append(detach)
        return detach

    def add_source(
        self,
        sample: Callable[[], Event | None],
        *,
        last: Callable[[], Event | None] | None = None,
    ) -> Callable[[], None]:
        """Call ``sample`` at every batch and hand on the event it returns, if any (a
        simulation's world: :mod:`btcap.sim.running.worldfeed`). Returns a detach, which samples
        once more (with ``last`` if given: a source that thins its events out says all
        at the end), so the last change is kept."""
        self._sources.append(sample)

        def detach() -> None:
            if sample in self._sources:
                self._sample(last or sample)
                self._sources.remove(sample)

        self._detach.append(detach)
        return detach

    def _sample(self, sample: Callable[[], Event | None]) -> None:
        ev = sample()
        if ev is not None:
            self._pending.append(ev)

    # -- events -----------------------------------------------------------------------
    def emit(self, ev: Event) -> None:
        """Queue an event for the next batch."""
        self._pending.append(ev)

    def _emit_run(self, ev: Event) -> None:
        """A run starts or ends: the trees' states as they are now go first, so that the
        page and a replay show them in step with it even when batches are far apart in
        clock time (a run on virtual time covers minutes between two batches)."""
        for tap in self._taps:
            self._flush_tap(tap)
        self._pending.append(ev)

    def _emit_hosted(self, ev: Event) -> None:
        """A run a robot's slot took up or put down, handed on as one of a capability's
        (:meth:`_emit_run`) unless the capability node it runs for is watched here too:
        that node reports the run (as its origin sees it, moves and losses included)."""
        key = ev["execution"]
        if ev["phase"] == "start":
            origin, node = ev["origin"], ev["node"]
            if any(t.robot == origin and node in t.capabilities for t in self._taps):
                return
            self._hosting.add(key)
        elif key in self._hosting:
            self._hosting.discard(key)
        else:
            return  # its start was not handed on
        self._emit_run(ev)

    def _robot(self, robot: str, now: float) -> None:
        if robot not in self._status:
            self._status[robot] = "seen"
            self.emit({"t": now, "k": "robot", "robot": robot})

    def _team(self, robot: str, change: str, now: float) -> None:
        self._robot(robot, now)
        if self._status[robot] != change:  # every robot reports each change: say it once
            self._status[robot] = change
            self.emit({"t": now, "k": "team", "robot": robot, "change": change})
            if change == "joined":
                self._last_join = (now, robot)

    def _on_team(self, ev: TeamEvent, robot: str, now: float) -> None:
        change = _STATUS.get(ev)
        if change is not None:
            self._team(robot, change, now)

    def _on_lost(self, lost: Lost) -> None:
        self._lost[str(lost.execution)] = f"{lost.executor}: {lost.why}"
        if len(self._lost) > _MAX_LOST:  # of a tree nobody added: never claimed
            del self._lost[next(iter(self._lost))]

    def _run_ended(self, execution: str, result: str) -> str | None:
        why = self._lost.pop(execution, None)
        node = _node_of(execution)
        self._ended[node] = (result, why)
        return why

    def _on_auction(self, rec: AuctionRecord) -> None:
        task = rec.task
        node = _node_of(str(task.execution))
        base = {"k": "auction", "id": str(rec.id), "execution": str(task.execution)}
        if rec.closed is None:
            self.emit(
                {
                    **base,
                    "t": rec.opened,
                    "phase": "open",
                    "auctioneer": rec.id.auctioneer,
                    "capability": task.interface,
                    "node": node,
                    "candidates": sorted(task.candidates),
                    "why": self._why(task.holder_robot, node, rec.opened),
                }
            )
            return
        out, won = rec.outcome, rec.result
        reasons = dict(rec.passed)
        self.emit(
            {
                **base,
                "t": rec.closed,
                "phase": "close",
                "auctioneer": rec.id.auctioneer,
                "bids": [[b.robot, b.cost] for b in out.ranking] if out is not None else [],
                "declined": dict(out.declined) if out is not None else {},
                "reasons": reasons if won is not None else {"auctioneer": "cancelled"},
                "winner": won.robot if isinstance(won, Assigned) else None,
            }
        )
        if not isinstance(won, Assigned):
            self._ended[node] = ("unassigned", None)

    def _why(self, holder: str | None, node: str, now: float) -> str:
        """Why this auction for ``node`` is held: the first one, a re-auction after its
        executor was lost (failure, lease lapse), a retry, or a re-evaluation."""
        last = self._ended.pop(node, None)
        before, self._asked[node] = self._asked.get(node), now
        if holder is not None:
            join = self._last_join
            if join is not None and (before is None or join[0] >= before):
                return f"re-evaluation: {join[1]} joined; {holder} runs it"
            return f"re-evaluation: may move from {holder}"
        if last is None:
            return "first request"
        result, why = last
        if result == "lost":
            return f"re-auction: executor lost ({why})" if why else "re-auction: executor lost"
        if result == "unassigned":
            return "retry: nobody took it last time"
        return f"new run (the last one {result})"

    # -- batching ---------------------------------------------------------------------
    def _flush_tap(self, tap: TreeTap) -> None:
        ev = tap.flush()
        if ev is not None:
            self._pending.append(ev)

    def flush(self) -> list[Event]:
        """Hand every change since the last flush on, as one batch; returns it."""
        pending = self._pending
        for tap in self._taps:
            ev = tap.flush()
            if ev is not None:
                pending.append(ev)
        for sample in self._sources:
            ev = sample()
            if ev is not None:
                pending.append(ev)
        if not pending:  # most batches of a --fast run: nothing changed
            return []
        batch, self._pending = pending, []
        for ev in batch:
            self.view.apply(ev)
        if self._recorder is not None:
            self._recorder.write(batch)
        if self._live is not None:
            self._live.write(batch)
        self._hub.publish(batch)
        return batch

    def _safe_flush(self) -> None:
        try:
            self.flush()
        except Exception as exc:  # a bad event must not end monitoring
            log.error("monitor.flush_failed", exc_info=exc)

    # -- for the server ---------------------------------------------------------------
    def snapshot(self) -> dict[str, Any]:
        return {**self.view.snapshot(), "mode": "live", "title": self.title}

    @property
    def hub(self) -> Hub:
        return self._hub

    @property
    def recording_failed(self) -> str | None:
        """Why the recording stopped before the run's end (a full disk), or None: a
        caller that says where it recorded says this instead."""
        return self._recorder.failed if self._recorder is not None else None


def _node_of(execution: str) -> str:
    """The node an execution id names, as its runs and auctions are matched by (the id's
    text without ``#number``: ``origin~incarnation:path``)."""
    return execution.rsplit("#", 1)[0]
