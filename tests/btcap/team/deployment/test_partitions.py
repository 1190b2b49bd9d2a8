"""Real sockets under real partitions: three ``btcap agent`` processes, each in its own
Linux network namespace, and an operator in a fourth, all on one bridge over CURVE tcp
(tests/netlab.py makes the namespaces and veths). During a ``btcap mission run`` the robot
running the long task is cut off (its bridge port down), healed once the operator has
declared it failed and the task's run ended, and awaited back in the team; then the long
task's robot again, cut the other way (its port out of the bridge); then the operator
itself, whose every robot gives its runs up and comes back after the heal.

Checked from what the processes wrote, not what the team believed:

- every tick of every run, in each robot's trace (tests/tracedwork.py), and when it was
  stopped: no task executes on two robots at once, not for a moment (a run acts from its
  first tick until it is stopped; the next run of its task ticks only after that);
- the operator's recording (``--record``): no run is credited to a robot that was
  declared failed while it ran, and a credited run ran to its end on that robot;
- every task completes once the network heals, and each healed robot rejoins.

Needs root, Linux and iproute2 (skipped with the reason otherwise); every process is
killed and reaped and every namespace deleted, whatever happens.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import AsyncIterator, Callable
from contextlib import AsyncExitStack, asynccontextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

import anyio
import anyio.abc
import pytest
import tracedwork
from anyio.streams.buffered import BufferedByteReceiveStream
from netlab import Lab, LabUnavailable, unavailable
from tracedwork import INTERFACES, read_trace

from btcap.cli import main

pytestmark = pytest.mark.slow

T = TypeVar("T")
ROBOTS = ("alpha", "beta", "gamma")
COST = {"alpha": 1.0, "beta": 2.0, "gamma": 3.0}
PORT = 7100
TICK_HZ = 20
#: A credited run ticked for its whole task, give or take one tick of the robots' trees.
TICK_S = 1 / TICK_HZ
TASK_S = 3.0
#: How long a task runs on a robot before that robot is cut off.
RUN_BEFORE_CUT_S = 0.5
#: The defaults' failure timeout (0.5 s) under the lease (1 s): the origin declares a
#: cut-off executor failed before its run stops (0.9 lease after the executor's newest
#: stamp the origin echoed), so only the fence keeps the next run from starting beside
#: it (before the fence, with a lease share of 0.8, this raced: seen 26 ms of overlap).
TIMING = (
    f"{{tick_hz: {TICK_HZ}, heartbeat_s: 0.1, failure_timeout_s: 0.5, lease_s: 1.0, "
    "keepalive_s: 0.05}"
)
MISSION = f"""\
btcap: 1
name: partitioned
root:
  type: Parallel
  name: mission
  children:
    - {{type: Work, name: long, inputs: {{task: long, seconds: {TASK_S}}}}}
    - {{type: Work, name: short, inputs: {{task: short, seconds: {TASK_S}}}}}
"""


# -- the team's files ----------------------------------------------------------------------
def write_config(lab: Lab, folder: Path, robot: str) -> Path:
    """``robot``'s agent file: bound to its address in its namespace, CURVE keys, the
    traced ``Work`` for a robot; a robot seeds the next one (a ring), the operator all."""
    if robot == "operator":
        seeds = list(ROBOTS)
    else:
        seeds = [ROBOTS[(ROBOTS.index(robot) + 1) % len(ROBOTS)]]
    seed_lines = "".join(
        f'    - {{robot: {s}, endpoint: "tcp://{lab.address(s)}:{PORT}"}}\n' for s in seeds
    )
    text = (
        f"btcap: 1\nrobot: {robot}\n"
        f"capabilities:\n  interfaces: [{folder / 'work.yaml'}]\n"
        f"network:\n  bind: tcp://{lab.address(robot)}:{PORT}\n  seeds:\n{seed_lines}"
        f"timing: {TIMING}\n"
        f"keys: {{secret: {folder / 'keys' / robot}.key_secret, trusted: {folder / 'keys'}}}\n"
    )
    if robot != "operator":
        args = {
            "interfaces": str(folder / "work.yaml"),
            "trace": str(folder / f"{robot}.trace"),
            "cost": COST[robot],
        }
        text += f'plugin: {{factory: "tracedwork:implementations", args: {json.dumps(args)}}}\n'
    path = folder / f"{robot}.yaml"
    path.write_text(text)
    return path


def btcap_in(lab: Lab, host: str, *args: str) -> list[str]:
    """``btcap ARGS`` run by this interpreter inside ``host``'s namespace, logging JSON."""
    return [
        *lab.prefix(host),
        sys.executable,
        "-m",
        "btcap",
        "--log-level",
        "info",
        "--log-json",
        *args,
    ]


def child_env(folder: Path) -> dict[str, str]:
    """This environment, with the robots' plugin importable: a copy of tracedwork.py in
    ``folder/plugin`` (not all of tests/, whose folders would shadow btcap's packages)."""
    plugin = folder / "plugin"
    if not plugin.exists():
        plugin.mkdir()
        shutil.copy(tracedwork.__file__, plugin)
    path = os.pathsep.join(p for p in (str(plugin), os.environ.get("PYTHONPATH")) if p)
    return {**os.environ, "PYTHONPATH": path}


@asynccontextmanager
async def process(
    cmd: list[str], log: Path, *, stdin: int | None = subprocess.DEVNULL
) -> AsyncIterator[anyio.abc.Process]:
    """A child writing stderr to ``log``; on exit still running, it gets SIGTERM and 5 s
    to leave, then SIGKILL, and is always reaped."""
    with log.open("wb") as err:
        proc = await anyio.open_process(
            cmd, stdin=stdin, stdout=subprocess.PIPE, stderr=err, env=child_env(log.parent)
        )
    try:
        yield proc
    finally:
        with anyio.CancelScope(shield=True):
            if proc.returncode is None:
                proc.send_signal(signal.SIGTERM)
                with anyio.move_on_after(5):
                    await proc.wait()
            if proc.returncode is None:
                proc.kill()
            await proc.aclose()


async def listening(proc: anyio.abc.Process, robot: str, log: Path) -> None:
    """Until ``btcap agent`` says it listens (it prints one line)."""
    assert proc.stdout is not None
    said = b""
    try:
        while b"listening" not in said:
            said += await proc.stdout.receive()
    except anyio.EndOfStream:
        said = await anyio.Path(log).read_text()
        raise AssertionError(f"agent {robot} ended before listening:\n{said}") from None


# -- what the operator records ---------------------------------------------------------
@dataclass
class Run:
    execution: str
    robot: str
    node: str
    start: float
    end: float | None = None
    result: str | None = None
    why: str | None = None
    seen: float = 0.0  #: when this test read its start (monotonic)


@dataclass
class Recording:
    """The operator's ``--record`` file, read as it grows."""

    path: Path
    offset: int = 0
    runs: dict[str, Run] = field(default_factory=dict)
    team: list[tuple[float, str, str, float]] = field(default_factory=list)
    finished: dict[str, Any] | None = None

    def read(self) -> None:
        if not self.path.exists():
            return
        with self.path.open("rb") as f:
            f.seek(self.offset)
            data = f.read()
        complete = data[: data.rfind(b"\n") + 1]
        self.offset += len(complete)
        now = time.monotonic()
        for line in complete.splitlines():
            ev = json.loads(line)
            kind = ev.get("k")
            if kind == "run" and ev["phase"] == "start":
                self.runs[ev["execution"]] = Run(
                    ev["execution"], ev["robot"], ev["node"], ev["t"], seen=now
                )
            elif kind == "run" and ev["phase"] == "end":
                run = self.runs[ev["execution"]]
                run.end, run.result, run.why = ev["t"], ev["result"], ev.get("why")
            elif kind == "team":
                self.team.append((ev["t"], ev["robot"], ev["change"], now))
            elif kind == "finished":
                self.finished = ev

    def running(self, node: str) -> Run | None:
        """The run of ``node`` under way now, if any."""
        live = [r for r in self.runs.values() if r.node.endswith(node) and r.end is None]
        return live[-1] if live else None

    def last_change(self, robot: str, change: str, after: float = -1.0) -> float | None:
        """When this test saw the operator record ``change`` of ``robot`` after ``after``."""
        seen = [s for _, r, c, s in self.team if r == robot and c == change and s > after]
        return seen[-1] if seen else None


# -- the test ------------------------------------------------------------------------------
@dataclass
class Cut:
    host: str  #: the one cut off
    how: str
    at: float
    executor: str  #: the robot running the long task when it was cut
    failed_seen: float = 0.0
    healed: float = 0.0
    rejoined_seen: float = 0.0


async def test_a_mission_survives_real_partitions_with_its_invariants(tmp_path: Path) -> None:
    if (why := unavailable()) is not None:
        pytest.skip(why)
    hosts = [*ROBOTS, "operator"]
    lab = Lab(hosts)
    try:
        lab.open()
    except LabUnavailable as exc:
        pytest.skip(str(exc))
    try:
        with anyio.fail_after(50):
            await _mission_under_partitions(lab, tmp_path)
    finally:
        lab.close()


async def _mission_under_partitions(lab: Lab, folder: Path) -> None:
    (folder / "keys").mkdir()
    for robot in [*ROBOTS, "operator"]:
        role = "operator" if robot == "operator" else "robot"
        assert main(["keys", "new", robot, "--role", role, "--dir", str(folder / "keys")]) == 0
    (folder / "work.yaml").write_text(INTERFACES)
    (folder / "mission.yaml").write_text(MISSION)
    configs = {r: write_config(lab, folder, r) for r in [*ROBOTS, "operator"]}
    record = Recording(folder / "operator.jsonl")
    cuts: list[Cut] = []
    async with AsyncExitStack() as stack:
        agents = {
            r: await stack.enter_async_context(
                process(
                    btcap_in(lab, r, "agent", str(configs[r]), "--until-stdin-closes"),
                    folder / f"{r}.log",
                    stdin=subprocess.PIPE,  # closed by a test killed mid-run: they leave
                )
            )
            for r in ROBOTS
        }
        with anyio.fail_after(20):
            async with anyio.create_task_group() as tg:
                for r, proc in agents.items():
                    tg.start_soon(listening, proc, r, folder / f"{r}.log")
        mission = ["mission", "run", str(folder / "mission.yaml"), "--timeout", "30"]
        mission += ["--config", str(configs["operator"]), "--record", str(record.path)]
        operator = await stack.enter_async_context(
            process(btcap_in(lab, "operator", *mission), folder / "operator.log")
        )
        out: list[str] = []
        async with anyio.create_task_group() as tg:
            tg.start_soon(_collect, operator, out)
            cuts.append(await _cut(lab, record, operator, out, "down"))
            cuts.append(await _cut(lab, record, operator, out, "detach"))
            cuts.append(await _cut(lab, record, operator, out, "down", origin=True))
            with anyio.fail_after(20):
                code = await operator.wait()
        record.read()
        _report(folder, cuts, record, out)
        assert code == 0, _said(folder, out)
    _check(folder, record, cuts, out)


async def _collect(proc: anyio.abc.Process, out: list[str]) -> None:
    """The operator's stdout, line by line (shown when something fails)."""
    assert proc.stdout is not None
    lines = BufferedByteReceiveStream(proc.stdout)
    try:
        while True:
            out.append((await lines.receive_until(b"\n", 65536)).decode())
    except (anyio.EndOfStream, anyio.IncompleteRead):
        pass


async def _until(
    what: str,
    cond: Callable[[], T | None],
    record: Recording,
    operator: anyio.abc.Process,
    out: list[str],
    *,
    timeout: float = 10.0,
) -> T:
    """Until ``cond()`` holds (re-reading the recording), at most ``timeout`` seconds."""
    with anyio.move_on_after(timeout):
        while True:
            record.read()
            if (value := cond()) is not None and value is not False:
                return value
            if operator.returncode is not None:
                raise AssertionError(
                    f"the mission ended while waiting for {what}:\n" + "".join(out)
                )
            await anyio.sleep(0.02)
    raise AssertionError(f"no {what} within {timeout} s:\n" + "".join(out))


async def _cut(
    lab: Lab,
    record: Recording,
    operator: anyio.abc.Process,
    out: list[str],
    how: str,
    *,
    origin: bool = False,
) -> Cut:
    """Once the long task has run a while, cut off the robot running it (``origin``: the
    operator, whose task that is); heal once the operator has declared the cut-off robots
    failed and the task's run ended (it moved, or waits for the network), and wait until
    they are back in the operator's team."""

    def settled() -> Run | None:
        """The long task's run, once it has gone on a while and the team has been still as
        long (a robot rejoining is offered running work: it may move at once)."""
        run = record.running("/long")
        joins = [seen for _, _, change, seen in record.team if change == "joined"]
        since = max([run.seen, *joins]) if run is not None else time.monotonic()
        return run if time.monotonic() - since >= RUN_BEFORE_CUT_S else None

    run = await _until("a robot running the long task", settled, record, operator, out)
    host = "operator" if origin else run.robot
    cut = Cut(host, how, time.monotonic(), run.robot)
    lab.cut(host, how)
    gone = list(ROBOTS) if origin else [run.robot]

    def ended() -> bool:
        return record.runs[run.execution].end is not None

    def failed() -> float | None:
        seen = [record.last_change(r, "failed", after=cut.at) for r in gone]
        return None if None in seen else max(s for s in seen if s is not None)

    await _until("the long task's run to end", ended, record, operator, out)
    cut.failed_seen = await _until(f"{', '.join(gone)} failed", failed, record, operator, out)
    cut.healed = time.monotonic()
    lab.heal(host)

    def rejoined() -> float | None:
        seen = [record.last_change(r, "joined", after=cut.healed) for r in gone]
        return None if None in seen else max(s for s in seen if s is not None)

    cut.rejoined_seen = await _until(f"{', '.join(gone)} back", rejoined, record, operator, out)
    return cut


# -- checking what was written -------------------------------------------------------------
@dataclass
class Executed:
    """One run as its robot's trace shows it: first and last tick."""

    robot: str
    task: str
    run: str
    first: float
    last: float  #: its last tick, or when it was stopped (it acted until then)
    ticked: float = 0.0  #: its last tick

    def __post_init__(self) -> None:
        self.ticked = self.last


def _executed(folder: Path) -> list[Executed]:
    runs: dict[tuple[str, str], Executed] = {}
    for robot in ROBOTS:
        for tick in read_trace(folder / f"{robot}.trace"):
            key = (robot, tick["run"])
            seen = runs.get(key)
            if seen is None:
                if not tick.get("stop"):
                    runs[key] = Executed(robot, tick["task"], tick["run"], tick["t"], tick["t"])
            else:
                seen.last = max(seen.last, tick["t"])
                seen.ticked = seen.last if not tick.get("stop") else seen.ticked
    return sorted(runs.values(), key=lambda e: e.first)


def _check(folder: Path, record: Recording, cuts: list[Cut], out: list[str]) -> None:
    executed = _executed(folder)
    # No task executed on two robots at once, not for a moment.
    for i, a in enumerate(executed):
        for b in executed[i + 1 :]:
            if a.task == b.task:
                overlap = min(a.last, b.last) - max(a.first, b.first)
                assert overlap < 0, f"{a} and {b} acted at once for {overlap:.3f} s"
    # Nothing credited to a robot declared failed while it ran, and a credited run ran to
    # its end on that robot.
    by_run = {(e.robot, e.run): e for e in executed}
    succeeded = [r for r in record.runs.values() if r.result == "succeeded"]
    for run in succeeded:
        gone = [
            (t, change)
            for t, robot, change, _ in record.team
            if robot == run.robot and change in ("failed", "left") and run.start <= t <= run.end
        ]
        assert not gone, f"{run} credited, but {run.robot} was declared {gone} while it ran"
        ran = by_run.get((run.robot, run.execution.replace("/", ".")))
        assert ran is not None, f"{run} credited, but {run.robot} never ticked it"
        assert ran.ticked - ran.first >= TASK_S - TICK_S, f"{run} credited after {ran}"
    # Every task completed once the network healed; each healed robot came back.
    assert sorted(r.node.rsplit("/", 1)[-1] for r in succeeded) == ["long", "short"], out
    assert record.finished is not None
    assert record.finished["result"] == "succeeded"
    assert all(c.rejoined_seen > c.healed for c in cuts), cuts


def _said(folder: Path, out: list[str]) -> str:
    logs = "".join(f"--- {r}\n{(folder / f'{r}.log').read_text()}" for r in (*ROBOTS, "operator"))
    return "".join(out) + logs


def _report(folder: Path, cuts: list[Cut], record: Recording, out: list[str]) -> None:
    """Timings and what the processes logged above info, for a person reading ``-s``."""
    executed = _executed(folder)
    lines = []
    for c in cuts:
        old = [e for e in executed if e.task == "long" and e.robot == c.executor and e.first < c.at]
        new = [e for e in executed if e.task == "long" and e.first > c.at]
        stop = old[-1].last - c.at if old else float("nan")
        start = new[0].first - c.at if new else float("nan")
        lines.append(
            f"cut {c.host} ({c.how}) while {c.executor} ran the long task: {c.executor}'s "
            f"last tick +{stop:.3f} s, {new[0].robot if new else '?'}'s first +{start:.3f} s; "
            f"failed seen +{c.failed_seen - c.at:.3f} s, healed +{c.healed - c.at:.3f} s, "
            f"back in the team +{c.rejoined_seen - c.healed:.3f} s after healing"
        )
    lines += [f"run {e.robot} {e.task} {e.first:.3f}..{e.last:.3f} {e.run}" for e in executed]
    for r in (*ROBOTS, "operator"):
        for line in (folder / f"{r}.log").read_text().splitlines():
            ev = json.loads(line) if line.startswith("{") else {"event": line, "level": "?"}
            if ev.get("level") != "info":
                lines.append(f"{r}: {ev}")
    text = "\n".join(lines)
    (folder / "report.txt").write_text(text)
    print(text)
