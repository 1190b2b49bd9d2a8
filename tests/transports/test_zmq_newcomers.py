"""How a connection is named and shut (transports/zmq_newcomers.py): only a connection
accepted on our endpoint, only the very socket named, and no descriptor left behind
when the number now holds something else."""

from __future__ import annotations

import asyncio
import os
import socket
import time
from collections.abc import Iterator

import anyio
import anyio.lowlevel
import pytest

from btcap.transports.base import TransportStats
from btcap.transports.zmq_newcomers import (
    NO_HELLO,
    STALL_S,
    NewcomerWatch,
    local_address,
    shut,
    socket_key,
)


def copies(fd: int) -> int:
    """How many of this process's descriptors are ``fd``'s file (the pipe or socket it
    names): other threads of the suite open and close files of their own meanwhile."""
    target = os.readlink(f"/proc/self/fd/{fd}")
    found = 0
    for name in os.listdir("/proc/self/fd"):
        try:
            found += os.readlink(f"/proc/self/fd/{name}") == target
        except OSError:  # closed since it was listed
            continue
    return found


@pytest.fixture
def pair() -> Iterator[tuple[socket.socket, socket.socket, socket.socket]]:
    """A listener on loopback, a client and the connection it accepted."""
    with socket.create_server(("127.0.0.1", 0)) as listener:
        client = socket.create_connection(listener.getsockname())
        accepted, _ = listener.accept()
        with client, accepted:
            yield listener, client, accepted


def test_an_accepted_connection_is_named_and_shut(
    pair: tuple[socket.socket, socket.socket, socket.socket],
) -> None:
    listener, client, accepted = pair
    local = local_address(f"tcp://127.0.0.1:{listener.getsockname()[1]}")
    key = socket_key(accepted.fileno(), local)
    assert key is not None
    assert socket_key(listener.fileno(), local) is None  # the listener is no connection
    assert socket_key(client.fileno(), local) is None  # not accepted on our endpoint
    assert not shut(accepted.fileno(), ("other", 1))  # not the socket named
    assert shut(accepted.fileno(), key)
    assert client.recv(1) == b""  # the peer sees the end


def test_a_number_that_holds_no_socket_leaves_nothing_open() -> None:
    """An accept event read after its descriptor's number went to a pipe (libzmq's own
    mailboxes use them): the duplicate made to look at it is closed again."""
    read, write = os.pipe()
    try:
        before = copies(read)  # (the pipe's two ends)
        assert socket_key(read, 5) is None
        assert not shut(read, (0, 0))
        assert copies(read) == before  # the duplicate made to look at it is closed
    finally:
        os.close(read)
        os.close(write)


def test_a_closed_number_is_nothing() -> None:
    read, write = os.pipe()
    os.close(read)
    os.close(write)
    assert socket_key(read, 5) is None
    assert not shut(read, (0, 0))


@pytest.mark.parametrize(
    ("bound", "local"),
    [
        ("tcp://127.0.0.1:7101", 7101),
        ("tcp://[::1]:7101", 7101),
        ("ipc:///tmp/a.sock", "/tmp/a.sock"),
        ("ipc://@abstract", b"\0abstract"),
        ("inproc://x", None),
    ],
)
def test_local_address(bound: str, local: object) -> None:
    assert local_address(bound) == local


async def test_a_stalled_loop_does_not_count_against_a_newcomer(
    pair: tuple[socket.socket, socket.socket, socket.socket],
) -> None:
    """The loop is held up past a newcomer's deadline (its hello, sent meanwhile, unread):
    it is not closed as the loop wakes, only once its deadline passes with the loop live."""
    listener, client, accepted = pair
    deadline = 0.3
    watch = NewcomerWatch(
        f"tcp://127.0.0.1:{listener.getsockname()[1]}", TransportStats(), "a", deadline, cap=8
    )
    with anyio.fail_after(10):
        try:
            watch.accepted(accepted.fileno())
            time.sleep(deadline + 2 * STALL_S)  # noqa: ASYNC251 - the stall under test
            woke = asyncio.get_running_loop().time()
            while (due := watch.book.next_due()) is not None and due <= woke:
                await anyio.lowlevel.checkpoint()  # until the late timer has fired
            assert watch.stats.by_reason.get(NO_HELLO, 0) == 0
            assert due is not None  # still waiting: its wait paused for the stall
            client.setblocking(False)
            with pytest.raises(BlockingIOError):
                client.recv(1)  # still open
            while not watch.stats.by_reason.get(NO_HELLO, 0):  # noqa: ASYNC110 - no event
                await anyio.sleep(0.01)
            client.setblocking(True)
            assert client.recv(1) == b""  # silent with the loop live: closed after all
        finally:
            watch.close()
