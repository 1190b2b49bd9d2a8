"""``btcap sim serve``: the simulated world behind ROS 2 in a process of its own, two
``btcap agent`` processes (examples/ros2/sim, RosAction implementations) driving its
robots through ROS 2 only, and a mission run from a third (``btcap mission run``): the
multi-process shape of a real deployment. Every process is stopped and reaped."""

from __future__ import annotations

import os
import re
import signal
import sys
from collections.abc import AsyncIterator, Callable
from contextlib import AsyncExitStack, asynccontextmanager
from pathlib import Path
from typing import BinaryIO

import anyio
import anyio.abc
import pytest

pytestmark = [pytest.mark.ros, pytest.mark.slow]

EXAMPLE = Path(__file__).resolve().parents[3] / "examples" / "ros2" / "sim"


def _btcap(*args: str) -> list[str]:
    return [sys.executable, "-m", "btcap", *args]


def _files(out: Path) -> tuple[BinaryIO, BinaryIO]:
    return open(out.with_suffix(".out"), "wb"), open(out.with_suffix(".err"), "wb")


@asynccontextmanager
async def _process(
    args: list[str], out: Path, env: dict[str, str]
) -> AsyncIterator[anyio.abc.Process]:
    """``args`` with stdout and stderr to ``out`` (.out, .err); killed and reaped on exit
    if still running."""
    stdout, stderr = _files(out)
    with stdout, stderr:
        proc = await anyio.open_process(args, stdout=stdout, stderr=stderr, env=env)
    try:
        yield proc
    finally:
        with anyio.CancelScope(shield=True):
            if proc.returncode is None:
                proc.kill()
            await proc.aclose()


async def _until(proc: anyio.abc.Process, out: Path, said: Callable[[str], bool]) -> str:
    """What ``proc`` wrote on stdout once ``said`` holds of it; fails, with its stderr, if
    it exits first."""
    while True:
        text = out.with_suffix(".out").read_text()
        if said(text):
            return text
        if proc.returncode is not None:
            pytest.fail(
                f"{out.name} exited ({proc.returncode}): {out.with_suffix('.err').read_text()}"
            )
        await anyio.sleep(0.05)


async def test_agents_in_processes_drive_the_served_world_through_ros2(
    ros_domain: int, tmp_path: Path
) -> None:
    env = {**os.environ, "ROS_DOMAIN_ID": str(ros_domain), "PYTHONUNBUFFERED": "1"}
    with anyio.fail_after(240):
        async with AsyncExitStack() as stack:
            world = tmp_path / "world"
            server = await stack.enter_async_context(
                _process(_btcap("sim", "serve", "--ros2", str(EXAMPLE / "world.yaml")), world, env)
            )
            await _until(server, world, lambda t: "serving ros2-room behind ROS 2" in t)
            for robot in ("husky1", "bebop1"):
                agent = await stack.enter_async_context(
                    _process(_btcap("agent", str(EXAMPLE / f"{robot}.yaml")), tmp_path / robot, env)
                )
                await _until(agent, tmp_path / robot, lambda t: "listening" in t)
            mission = _btcap(
                "mission",
                "run",
                str(EXAMPLE / "mission.yaml"),
                "--config",
                str(EXAMPLE / "operator.yaml"),
                "--timeout",
                "120",
            )
            done = await anyio.run_process(mission, env=env, check=False)
            report = done.stdout.decode()
            assert done.returncode == 0, (report, done.stderr.decode())
            server.send_signal(signal.SIGINT)
            assert await server.wait() == 128 + signal.SIGINT
    assert "mission succeeded" in report
    # The summary's lines: each place explored by one robot, what it found as an output.
    ran = re.findall(r"explore/(east|south): succeeded on (husky1|bebop1) \(found=\d+\)", report)
    assert sorted(place for place, _ in ran) == ["east", "south"], report
    # The world served each robot's goals through its ROS 2 actions: every explore the
    # mission ran came as a navigation goal and an explore goal to that robot's servers.
    served = (world.with_suffix(".out")).read_text()
    for robot in {who for _, who in ran}:
        n = sum(1 for _, who in ran if who == robot)
        assert f"served {robot}: explore {n}, navigate_to_pose {n}" in served, served
    for robot in {"husky1", "bebop1"} - {who for _, who in ran}:
        assert f"served {robot}: nothing" in served, served
