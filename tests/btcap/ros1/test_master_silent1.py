"""A ROS 1 master that takes connections and never answers (a stopped rosmaster, a
listener nobody serves) holds nothing for ever: the bridge's start fails in one line
naming the master and the call while the event loop runs on, and a robot's rospy process
says the stall once, counts its services gone, and goes on once the master answers."""

from __future__ import annotations

import os
import re
import signal
import socket

import anyio
import pytest
from conftest import Servers
from rosmaster1 import Master
from structlog.testing import capture_logs
from tools1 import bridge_on, settle

from btcap.ros import rpc1
from btcap.ros.client1 import PROBE_S, Ros1Bridge
from btcap.ros.errors import RosError
from btcap.team.rossettings import RosSettings

pytestmark = pytest.mark.ros1


async def test_a_master_that_never_answers_fails_the_start_naming_the_call() -> None:
    ticks = 0

    async def tick() -> None:
        nonlocal ticks
        while True:
            ticks += 1
            await anyio.sleep(0.01)

    with socket.create_server(("127.0.0.1", 0)) as listener:  # taken, never answered
        uri = f"http://127.0.0.1:{listener.getsockname()[1]}/"
        bridge = Ros1Bridge(RosSettings(backend="ros1", master_uri=uri), robot="husky1")

        async def start() -> None:
            try:
                await bridge.__aenter__()
            finally:
                tg.cancel_scope.cancel()

        with anyio.fail_after(30):
            async with anyio.create_task_group() as tg:
                tg.start_soon(tick)
                with pytest.raises(RosError) as err:
                    await start()
    assert str(err.value) == (
        f"ROS 1 master {uri} does not answer getPid (no answer within {PROBE_S} s): start "
        "one (`roscore`) or set ros.master_uri (else ROS_MASTER_URI) to where it runs"
    )
    assert ticks > 1  # the loop ran while the start waited
    assert bridge.process is None
    await bridge.__aexit__(None, None, None)


async def test_a_stalled_master_is_said_once_and_its_services_count_as_gone(
    master: Master, servers: Servers
) -> None:
    """rosgraph's own proxy has no timeout: the process's poller waited for the master's
    answer for ever, and the service stayed ready."""
    assert master.process is not None
    with anyio.fail_after(45), capture_logs() as logs:
        async with bridge_on(master) as bridge:
            client = bridge.service_client("std_srvs/SetBool", "set_flag")
            await settle(lambda: client.ready)
            os.kill(master.process.pid, signal.SIGSTOP)
            try:
                await settle(lambda: not client.ready)
            finally:
                os.kill(master.process.pid, signal.SIGCONT)
            await settle(lambda: client.ready)  # it asks on, and the master answers
    (notice,) = [e["why"] for e in logs if e["event"] == "btcap.ros1.notice"]
    uri = re.escape(master.uri)
    assert re.fullmatch(
        rf"ROS 1 master {uri}: (getPid|lookupService): no answer within 1\.0 s \(until it "
        r"answers, this robot's services count as gone and its peers' types are unknown\)",
        notice,
    )


def test_a_real_masters_failure_code_is_an_answer_naming_the_call(master: Master) -> None:
    with pytest.raises(rpc1.RosCallError) as err:
        rpc1.call(master.uri, "lookupService", "/btcap_test", "/nobody")
    assert err.value.answered
    assert str(err.value).startswith(f"ROS 1 master {master.uri}: lookupService: refused: ")
    assert "\n" not in str(err.value)
    assert rpc1.call(master.uri, "getPid", "/btcap_test") == master.process.pid  # type: ignore[union-attr]
