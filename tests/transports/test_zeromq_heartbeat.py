"""ZMTP heartbeats: a DEALER whose peer went silent drops the link and dials afresh. A
peer process stopped with SIGSTOP keeps its tcp connections open in the kernel, so
without heartbeats the link would look alive for ever. Both a peer frozen at once and
one frozen after its ROUTER's PINGs reached us: a ROUTER-only design (its PINGs carrying
a TTL for the DEALER) drops the second but never the first, since a DEALER arms the TTL
only on a first PING (issue 22)."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys

import anyio
import pytest
from anyio.streams.buffered import BufferedByteReceiveStream

from btcap.actors import Address, AskTimeout
from tests.transports.peer_process import READY, Echo, Echoed
from tests.transports.test_zeromq import PEER_SCRIPT, eventually, zmq_system

pytestmark = pytest.mark.slow


@pytest.mark.parametrize("pinged_s", [2.2, 0.0], ids=["frozen-after-its-pings", "frozen-at-once"])
async def test_a_dealer_drops_its_link_to_a_peer_gone_silent(pinged_s: float) -> None:
    with anyio.fail_after(40):
        async with zmq_system("parent", "tcp://127.0.0.1:*") as (system, transport):
            args = [sys.executable, str(PEER_SCRIPT), "--id", "child", "--bind"]
            args += ["tcp://127.0.0.1:*", "--peer", f"parent={transport.endpoint}"]
            args += ["--lifetime", "30"]
            process = await anyio.open_process(args, stdin=subprocess.PIPE, stderr=None)
            try:
                assert process.stdout is not None
                line = await BufferedByteReceiveStream(process.stdout).receive_until(b"\n", 4096)
                assert line.decode().startswith(READY)
                await eventually(lambda: "child" in transport.peers(), "child said hello")
                echo = system.ref(Address("child", "echo"))
                assert await echo.ask(Echo("up")) == Echoed("up", "child")
                link = transport.routing_id("child")
                await anyio.sleep(pinged_s)  # the peer's ROUTER PINGs us each second
                os.kill(process.pid, signal.SIGSTOP)
                try:
                    # An unanswered PING drops the link within a few seconds, and a
                    # fresh DEALER (a new routing id) dials again.
                    await eventually(
                        lambda: transport.routing_id("child") != link,
                        "the link to the silent peer dropped and redialled",
                        limit=10.0,
                    )
                finally:
                    os.kill(process.pid, signal.SIGCONT)
                # The resumed child may answer on its own old link, which this side
                # dropped too and the child has yet to notice: that reply is lost (at
                # most once), so ask again until its link is redialled as well.
                for _ in range(5):
                    with contextlib.suppress(AskTimeout):
                        assert await echo.ask(Echo("back"), timeout=2.0) == Echoed("back", "child")
                        break
                else:
                    pytest.fail("no answer from the resumed peer in 5 asks")
            finally:
                process.kill()
                with anyio.CancelScope(shield=True):
                    await process.wait()
                await process.aclose()
