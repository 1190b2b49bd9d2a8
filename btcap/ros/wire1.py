"""The frames between a robot's ROS 1 bridge (:mod:`btcap.ros.client1`, in the agent's
process) and its rospy process (:mod:`btcap.ros.child1`): msgpack-encoded msgspec
structs over a pipe. Messages travel as genpy's own serialization (``data``), so the
wire keeps every ROS 1 type exactly and the child needs no per-type code.

``cid`` numbers a client (action client, service proxy, publisher, subscriber), ``gid`` a
goal and ``qid`` a service call, all chosen by the bridge.
"""

from __future__ import annotations

import msgspec

__all__ = [
    "Accepted",
    "Call",
    "Cancel",
    "Done",
    "Down",
    "Drop",
    "Feedback",
    "Goal",
    "Message",
    "Mismatch",
    "Notice",
    "Open",
    "Publish",
    "Ready",
    "Reply",
    "Stop",
    "Up",
    "decode_down",
    "decode_up",
    "encode",
]


class _Frame(msgspec.Struct, array_like=True, tag=True):
    pass


# -- bridge -> rospy process ----------------------------------------------------------
class Open(_Frame):
    """Make a client: ``kind`` is ``action``, ``service``, ``publisher`` or ``subscriber``;
    ``depth`` and ``latch`` are a topic's queue size and latching."""

    cid: int
    kind: str
    type_name: str
    name: str
    depth: int = 10
    latch: bool = False


class Drop(_Frame):
    """Unregister client ``cid``."""

    cid: int


class Goal(_Frame):
    cid: int
    gid: int
    data: bytes


class Cancel(_Frame):
    gid: int


class Call(_Frame):
    cid: int
    qid: int
    data: bytes


class Publish(_Frame):
    cid: int
    data: bytes


class Stop(_Frame):
    """Cancel the open goals, unregister everything, leave the master, exit."""


# -- rospy process -> bridge ----------------------------------------------------------
class Up(_Frame):
    """The node is registered (``error`` empty), or why it could not start."""

    error: str = ""


class Ready(_Frame):
    """Whether client ``cid``'s server answers now (sent on every change)."""

    cid: int
    ready: bool


class Accepted(_Frame):
    gid: int


class Feedback(_Frame):
    gid: int
    data: bytes


class Done(_Frame):
    """Goal ``gid`` ended with actionlib_msgs/GoalStatus ``status`` (its ``text``)."""

    gid: int
    status: int
    text: str
    data: bytes


class Reply(_Frame):
    """Call ``qid``'s response (``data``), or why it failed (``error``)."""

    qid: int
    data: bytes = b""
    error: str = ""


class Message(_Frame):
    cid: int
    data: bytes


class Mismatch(_Frame):
    """Client ``cid``'s peer has another type than the client (``found``: its type, said
    in one phrase), or, ``found`` empty, no more (sent on every change): an action
    server's or a publisher's type from the master, a service's from its probe header."""

    cid: int
    found: str


class Notice(_Frame):
    """Something the robot's user should know (the master restarted), in one line."""

    text: str


Down = Open | Drop | Goal | Cancel | Call | Publish | Stop
UpFrame = Up | Ready | Accepted | Feedback | Done | Reply | Message | Mismatch | Notice

_encoder = msgspec.msgpack.Encoder()
_down = msgspec.msgpack.Decoder(Down)
_up = msgspec.msgpack.Decoder(UpFrame)

encode = _encoder.encode


def decode_down(data: bytes) -> Down:
    frame: Down = _down.decode(data)
    return frame


def decode_up(data: bytes) -> UpFrame:
    frame: UpFrame = _up.decode(data)
    return frame
