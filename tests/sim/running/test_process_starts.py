"""How a distributed run starts its robots' processes: a few at a time, each with its
ready deadline from its own start, and one that does not come up named with why.

The processes are real child processes that stand in for ``btcap agent``: each says it
listens only when the test writes a line to its stdin (or never, or exits first), so
what is judged is when the host starts them, counted, not how fast a machine is."""

from __future__ import annotations

import itertools
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import anyio
import pytest

from btcap.actors import Clock
from btcap.sim.mission.scenario import load_scenario
from btcap.sim.running.distributed import ProcessHost
from btcap.sim.running.hosts import registry
from btcap.team.deployment.spawn import AsyncAgentProcess

DATA = Path(__file__).resolve().parents[1] / "data"

#: Says it listens once a line arrives on stdin, then stays until stdin closes.
WHEN_TOLD = """\
import sys
name = sys.argv[1]
if sys.stdin.readline():
    print(f"agent {name} listening on tcp://127.0.0.1:1", flush=True)
    sys.stdin.read()
"""
#: Wall seconds the stand-ins have to listen where one must not: the test waits that long.
READY_S = 4.0
#: Exits at once, before it listens.
EXITS = "import sys; sys.exit(3)"


class Starts:
    """Starts stand-in processes for a host, and counts how many were starting at once:
    started and not yet told to listen (the host holds a robot's turn until it listens)."""

    def __init__(self, script: dict[str, str] | None = None) -> None:
        self.procs: list[AsyncAgentProcess] = []
        self.told = 0
        self.most_at_once = 0
        self._script = script or {}

    async def __call__(self, path: Path, name: str) -> AsyncAgentProcess:
        self.most_at_once = max(self.most_at_once, len(self.procs) + 1 - self.told)
        code = self._script.get(name, WHEN_TOLD)
        process = await anyio.open_process(
            [sys.executable, "-c", code, name],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
        )
        proc = AsyncAgentProcess([name], process)
        self.procs.append(proc)
        return proc

    async def tell(self, proc: AsyncAgentProcess) -> None:
        """Let ``proc`` listen, and wait until the host has read that it does."""
        self.told += 1
        assert proc.process.stdin is not None
        await proc.process.stdin.send(b"go\n")
        await _until(lambda: proc.ready)


def host(starts: Starts, **options: float) -> ProcessHost:
    s = load_scenario(DATA / "small.yaml")
    return ProcessHost(s, Clock(speedup=1.0), registry(), s.grid(), spawn=starts, **options)


async def _until(cond: Callable[[], bool]) -> None:
    """Check ``cond`` every 10 ms (the test's fail_after bounds it)."""
    for _ in itertools.count():
        if cond():
            return
        await anyio.sleep(0.01)


async def _started(starts: Starts, n: int) -> None:
    await _until(lambda: len(starts.procs) >= n)


async def test_fifty_robots_start_three_at_a_time() -> None:
    starts = Starts()
    names = [f"r{i}" for i in range(50)]
    with anyio.fail_after(120):
        async with host(starts, starts_at_once=3) as robots:
            for name in names:
                robots.start(name)
            for i in range(len(names)):  # each one let listen in turn, oldest first
                await _started(starts, min(i + 3, len(names)))
                await starts.tell(starts.procs[i])
            assert robots.present() == set(names)
            assert robots.errors == []
            assert robots.starts.peak == 3
    assert starts.most_at_once == 3  # never more started and not yet listening
    assert all(not p.alive() for p in starts.procs)


async def test_a_robot_that_leaves_while_waiting_for_its_turn_is_never_started() -> None:
    starts = Starts()
    with anyio.fail_after(60):
        async with host(starts, starts_at_once=1) as robots:
            robots.start("first")
            robots.start("second")
            await _started(starts, 1)
            robots.leave("second")  # still waiting for first's turn to end
            await starts.tell(starts.procs[0])
            robots.start("third")
            await _started(starts, 2)
            await starts.tell(starts.procs[1])
            assert [p.robot for p in starts.procs] == ["first", "third"]
            assert robots.present() == {"first", "third"}


async def test_a_robot_that_does_not_come_up_is_one_line_naming_it_and_why() -> None:
    """One never listens (its deadline passes, and the next starts then), one exits.
    The deadline holds "fine" too (from its start to its line, an interpreter's start on
    a busy machine): generous, not 0.5 s."""
    starts = Starts({"silent": WHEN_TOLD, "broken": EXITS})
    with anyio.fail_after(60):
        async with host(starts, starts_at_once=1, ready_s=READY_S) as robots:
            robots.start("silent")  # never told to listen
            robots.start("broken")
            robots.start("fine")
            await _started(starts, 3)
            await starts.tell(starts.procs[2])
            await _until(lambda: len(robots.errors) >= 2)
            assert robots.present() == {"fine"}
    errors = {e.robot: e.error for e in robots.errors}
    assert errors == {
        "silent": f"did not start: agent silent did not listen within {READY_S:g} s of its start",
        "broken": "did not start: the process of agent broken exited (code 3) before it "
        "listened (its log says why)",
    }
    assert all("\n" not in e for e in errors.values())


def test_starting_none_at_a_time_is_refused() -> None:
    with pytest.raises(ValueError, match="at_once=0"):
        host(Starts(), starts_at_once=0)


async def test_a_robot_that_leaves_and_joins_again_while_waiting_is_started_once() -> None:
    """Its start waiting for a turn goes on: a second start would be a second process
    for one robot, the first one's orphaned (present, bidding, never stopped)."""
    starts = Starts()
    with anyio.fail_after(60):
        async with host(starts, starts_at_once=1) as robots:
            robots.start("first")
            robots.start("second")
            await _started(starts, 1)
            robots.leave("second")  # still waiting for first's turn to end
            robots.start("second")  # and back before it had its turn
            await starts.tell(starts.procs[0])
            await _started(starts, 2)
            await starts.tell(starts.procs[1])
            robots.start("third")  # (so a second process of "second" would have come first)
            await _started(starts, 3)
            await starts.tell(starts.procs[2])
            assert [p.robot for p in starts.procs] == ["first", "second", "third"]
            assert robots.present() == {"first", "second", "third"}
    assert all(not p.alive() for p in starts.procs)


def _stopped(proc: AsyncAgentProcess) -> bool:
    """Whether the process is stopped by a signal (state T in /proc)."""
    stat = Path(f"/proc/{proc.pid}/stat").read_text()
    return stat.rpartition(")")[2].split()[0] == "T"


async def test_a_robot_that_fails_before_it_is_up_is_frozen_once_up() -> None:
    """Failing while its start waits for a turn, or while its process is not listening
    yet, it is frozen as it comes up (frozen earlier, it would miss its ready deadline);
    before, the failure was dropped and it worked while the manager counted it down."""
    starts = Starts()
    with anyio.fail_after(60):
        async with host(starts, starts_at_once=1) as robots:
            robots.start("first")
            robots.start("waiting")
            await _started(starts, 1)
            robots.fail("waiting")  # no process yet: it waits for first's turn
            robots.fail("first")  # a process, not listening yet
            await starts.tell(starts.procs[0])
            await _started(starts, 2)
            await starts.tell(starts.procs[1])
            first, waiting = starts.procs
            assert _stopped(first)
            assert _stopped(waiting)
            assert robots.present() == set()
            assert robots.errors == []
            robots.recover("waiting")
            await _until(lambda: not _stopped(waiting))
            assert robots.present() == {"waiting"}
            robots.recover("first")
    assert all(not p.alive() for p in starts.procs)
