"""A peer actor system in its own OS process, for the cross-process ZeroMQ tests.

Run as ``python peer_process.py --id ID --bind ENDPOINT [--peer ID=ENDPOINT ...]``. It
binds, spawns an :class:`EchoActor` at ``echo``, prints ``READY <endpoint>`` on stdout
and runs until its stdin is closed or reads ``quit`` (so it also ends when the parent
dies and the pipe closes), or ``--lifetime`` seconds pass, whichever comes first.

The message types live here so the test and the child share one definition.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import sys
from collections.abc import Sequence

from btcap.actors import Actor, ActorSystem, Address, Message, configure_logging, handler
from btcap.transports import MessageRegistry, ZmqTransport

__all__ = ["READY", "Echo", "EchoActor", "Echoed", "Relay", "main", "messages"]

READY = "READY "


class Echo(Message):
    text: str


class Echoed(Message):
    text: str
    by: str


class Relay(Message):
    """Ask ``target`` an :class:`Echo` of ``text`` and reply with what it answered."""

    target: Address
    text: str


def messages() -> MessageRegistry:
    return MessageRegistry([Echo, Echoed, Relay])


class EchoActor(Actor):
    """Answers echoes with its system's id; relays ask onwards, across the network."""

    @handler
    def echo(self, msg: Echo) -> Echoed:
        return Echoed(msg.text, self.system.id)

    @handler
    async def relay(self, msg: Relay) -> Message:
        reply: Message = await self.system.ref(msg.target).ask(Echo(msg.text), timeout=10.0)
        return reply


async def _until_told(lifetime: float) -> None:
    """Return when stdin says ``quit``, reaches EOF (parent gone), or time runs out."""
    loop = asyncio.get_running_loop()
    done: asyncio.Future[None] = loop.create_future()
    fd = sys.stdin.fileno()
    buffer = bytearray()

    def readable() -> None:
        chunk = os.read(fd, 4096)
        buffer.extend(chunk)
        if (not chunk or b"quit" in buffer) and not done.done():
            done.set_result(None)

    loop.add_reader(fd, readable)
    try:
        await asyncio.wait_for(done, lifetime)
    except TimeoutError:
        pass
    finally:
        loop.remove_reader(fd)


async def _serve(system_id: str, bind: str, peers: dict[str, str], lifetime: float) -> None:
    registry = messages()
    transport = ZmqTransport(system_id, bind, registry, peers=peers)
    async with ActorSystem(transport=transport, registry=registry) as system:
        system.spawn(EchoActor(), "echo")
        print(READY + transport.endpoint, flush=True)
        await _until_told(lifetime)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--id", required=True)
    parser.add_argument("--bind", required=True)
    parser.add_argument("--peer", action="append", default=[], metavar="ID=ENDPOINT")
    parser.add_argument("--lifetime", type=float, default=60.0)
    args = parser.parse_args(argv)
    peers = dict(p.split("=", 1) for p in args.peer)
    configure_logging("warning")  # to stderr; stdout carries only the READY line
    asyncio.run(_serve(args.id, args.bind, peers, args.lifetime))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
