"""``--distributed``: the same mission with every robot in its own OS process."""

from __future__ import annotations

import signal
from pathlib import Path

import anyio
import msgspec
import pytest

import btcap.sim.running.distributed
from btcap.actors import TimeSource
from btcap.sim.mission.scenario import Event, Scenario, load_scenario
from btcap.sim.running.distributed import ProcessHost, run_distributed
from btcap.sim.running.runner import Progress, run_scenario
from btcap.sim.world.grid import GridMap
from btcap.transports import MessageRegistry

DATA = Path(__file__).resolve().parents[1] / "data"
#: Wall seconds a run may take: a bound for hangs, far above the ~10 s one takes quiet.
RUN_S = 300.0


def scenario(name: str) -> Scenario:
    """A test scenario for robots in processes, on the wall clock at 1000 times real time:
    its time limit (20000 s: 20 s of wall time, which a machine loaded 12 deep on 2 cores
    spends starting the processes and running them slowly) ten times longer, and its
    protocol timing three times, up to the 300 s a lease may be (a 100 ms lease lapsed
    there again and again: the operator renews on the wall, and a loaded machine holds a
    process off for longer). The mission then takes as long as it takes, and no robot
    fails that did not."""
    s = load_scenario(DATA / f"{name}.yaml")
    a = s.agent
    agent = msgspec.structs.replace(
        a,
        heartbeat_s=3 * a.heartbeat_s,
        failure_timeout_s=3 * a.failure_timeout_s,
        lease_s=3 * a.lease_s,
        keepalive_s=3 * a.keepalive_s,
        auction_window_s=3 * a.auction_window_s,
        award_timeout_s=3 * a.award_timeout_s,
    )
    return msgspec.structs.replace(s, time_limit_s=10 * s.time_limit_s, agent=agent)


pytestmark = pytest.mark.slow


class Hosts:
    """A host factory that keeps the hosts it made, to look at their processes."""

    def __init__(self) -> None:
        self.made: list[ProcessHost] = []

    def __call__(
        self, s: Scenario, clock: TimeSource, reg: MessageRegistry, grid: GridMap
    ) -> ProcessHost:
        host = ProcessHost(s, clock, reg, grid)
        self.made.append(host)
        return host


async def test_small_mission_completes_with_robots_in_separate_processes(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Through :func:`run_distributed` (``run_scenario`` with process hosts), with its
    host class watched where it looks it up: the hosts it makes are process hosts."""
    s = scenario("small")
    hosts = Hosts()
    monkeypatch.setattr(btcap.sim.running.distributed, "ProcessHost", hosts)
    with anyio.fail_after(RUN_S):
        result = await run_distributed(s)
    assert result.completed
    assert result.errors == []
    assert result.summary["found"] == s.objects
    # Every robot ran in a child process, and every child is gone afterwards.
    (host,) = hosts.made
    assert sorted(host.started) == ["bebop1", "husky1", "spot1"]
    assert all(not p.alive() for p in host.started.values())
    # Work was spread over the team as in-process runs spread it.
    kinds = {(i.robot, i.kind) for i in result.timeline if i.kind != "move" and i.ok}
    assert ("bebop1", "explore") in kinds
    assert any(k == "decontaminate" for _, k in kinds)


async def test_a_robot_process_that_dies_is_reported_and_the_team_finishes() -> None:
    s = scenario("small")
    hosts = Hosts()
    killed: list[float] = []

    def kill_bebop(p: Progress) -> None:
        bebop = hosts.made[0].started.get("bebop1")
        if not killed and p.time > 0 and bebop is not None:
            bebop.send_signal(signal.SIGKILL)  # the Bebop's computer dies mid-mission
            killed.append(p.time)

    with anyio.fail_after(RUN_S):
        result = await run_scenario(s, host=hosts, on_progress=kill_bebop)
    assert killed
    assert [(e.robot, e.error) for e in result.errors] == [
        ("bebop1", f"process exited with code {-signal.SIGKILL}")
    ]
    assert ("crashed", "bebop1") in [(m.event, m.robot) for m in result.marks]
    assert result.completed  # the Husky explores what the Bebop would have


async def test_a_robot_that_leaves_while_its_process_starts_never_works() -> None:
    """The Bebop joins and leaves a millisecond of wall time later, long before its
    process listens: it is stopped then, not left running until the mission ends; or,
    while the others still hold the start turns (a busy machine), never started."""
    s = msgspec.structs.replace(
        scenario("dynamic"),
        events=[
            Event(at=30, robot="bebop1", kind="join"),
            Event(at=31, robot="bebop1", kind="leave"),
        ],
    )
    hosts = Hosts()
    with anyio.fail_after(RUN_S):
        result = await run_scenario(s, host=hosts)
    assert result.completed
    assert result.errors == []
    assert (result.robot_failures, result.robots_left) == (0, 1)
    assert not [i for i in result.timeline if i.robot == "bebop1"]
    proc = hosts.made[0].started.get("bebop1")
    assert proc is None or not proc.alive()


async def test_a_frozen_robot_process_is_declared_failed_and_credited_nothing() -> None:
    """SIGSTOP, unannounced: the team declares the Spot failed, its identification moves
    to the Husky, and nothing the Spot was doing is recorded as done after the verdict."""
    s = scenario("small")
    hosts = Hosts()
    frozen: list[float] = []

    def freeze_spot_mid_task(p: Progress) -> None:
        if not frozen and "spot1" in p.tasks:  # it holds work
            hosts.made[0].fail("spot1")  # SIGSTOP; thawed when the run ends
            frozen.append(p.time)

    with anyio.fail_after(RUN_S):
        result = await run_scenario(
            s, host=hosts, on_progress=freeze_spot_mid_task, progress_every_s=0.001
        )
    assert frozen
    assert result.completed
    assert result.executions_lost >= 1
    verdict = frozen[0] + s.agent.failure_timeout_s + 1.0
    late = [i for i in result.timeline if i.robot == "spot1" and i.ok and i.end > verdict]
    assert not late, f"credited to the frozen Spot after {verdict:.1f} s: {late}"
    identified = [i for i in result.timeline if i.kind == "identify" and i.ok]
    assert any(i.robot == "husky1" and i.start > frozen[0] for i in identified)
