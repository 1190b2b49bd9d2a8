"""The robot's ROS 1 client: a rospy node in a child process of its own, behind the same
bridge interface as ROS 2's :class:`~btcap.ros.client.RosBridge`.

rospy allows one ``init_node`` per process and never gives it up, and its callbacks run on
its own threads; a robot's ROS 1 side is therefore a child process
(:mod:`btcap.ros.child1`), one per bridge, spoken to over a socket pair of
:mod:`btcap.ros.wire1` frames. Sending is a short write from the tick; answers are read by
one reader thread, which completes the node's futures and stores feedback and messages
for the next tick, as rclpy's executor thread does, so nothing of ROS 1 ever runs on the
event loop. :meth:`Ros1Bridge.start` first asks the master its pid over XML-RPC with a short
timeout (:mod:`btcap.ros.rpc1`; rospy itself would retry an unreachable master forever) and
fails in one line;
:meth:`Ros1Bridge.close` has the process cancel the open goals, unregister everything from
the master and exit, and reaps it.
"""

from __future__ import annotations

import contextlib
import itertools
import os
import socket
import subprocess
import sys
import threading
from multiprocessing.connection import Connection
from typing import Any, ClassVar

from btcap.ros import rpc1, wire1
from btcap.ros.client import RosBridge
from btcap.ros.errors import RosError
from btcap.ros.facade1 import (
    ActionClient1,
    Future1,
    GoalHandle1,
    Node1,
    ServiceClient1,
    Subscription1,
)
from btcap.ros.interfaces1 import interface1
from btcap.ros.outbox1 import Outbox
from btcap.ros.peers import tell
from btcap.ros.versions import ROS1, Types
from btcap.team.rossettings import Qos, RosSettings
from btcap.transports.log import get_logger

__all__ = ["Ros1Bridge", "probe_master"]

log = get_logger(__name__)

#: Bounds, not measures: the master answers its pid in milliseconds, the rospy process
#: registers in about a second (imports), and leaves the master in well under one.
PROBE_S = 3.0
START_S = 60.0
STOP_S = 10.0
DEFAULT_MASTER = "http://localhost:11311/"
#: Types told to askers at most (then told again: a bound, not a measure).
_TOLD = 256
_UNREAD = "none of that publisher's messages reach this node"
_RESTART = ": restart the robot's agent (or make a new Ros1Bridge)"


def probe_master(uri: str) -> None:
    """Nothing if the ROS 1 master at ``uri`` answers ``getPid``; else RosError saying so
    in one line (blocks up to PROBE_S: call it off the event loop)."""
    try:
        rpc1.call(uri, "getPid", "/btcap_probe", timeout_s=PROBE_S)
    except rpc1.RosCallError as exc:
        raise RosError(
            f"ROS 1 master {uri} does not answer getPid ({exc.why}): start one (`roscore`) "
            "or set ros.master_uri (else ROS_MASTER_URI) to where it runs"
        ) from None


class Ros1Bridge(RosBridge):
    """One robot's ROS 1 node ``NAMESPACE/NODE_NAME`` on the master ``settings.master_uri``
    (else ``ROS_MASTER_URI``, else ``http://localhost:11311/``), in a process of its own.
    Used exactly as :class:`~btcap.ros.client.RosBridge`."""

    types: ClassVar[Types] = ROS1

    def __init__(self, settings: RosSettings | None = None, *, robot: str = "") -> None:
        super().__init__(settings, robot=robot)
        self.master_uri = (
            self.settings.master_uri or os.environ.get("ROS_MASTER_URI") or DEFAULT_MASTER
        )
        self.process: subprocess.Popen[bytes] | None = None
        self._conn: Connection | None = None
        self._reader: threading.Thread | None = None
        self._sock: socket.socket | None = None
        self._outbox: Outbox | None = None
        self._depths: dict[int, int] = {}  # a publisher's queue size, by cid
        self._ids = itertools.count(1)
        self._servers: dict[int, ActionClient1 | ServiceClient1] = {}
        self._handles: dict[int, GoalHandle1] = {}
        self._calls: dict[int, tuple[Future1, Any]] = {}
        self._subs: dict[int, Subscription1] = {}
        self._dead: str | None = None
        #: What each client is told as (``action /husky1/move_base``, its type), by cid,
        #: and the (asker, cid, type) already told (bounded: :meth:`mismatch`).
        self._labels: dict[int, tuple[str, str]] = {}
        self._told: set[tuple[str, int, str]] = set()

    # -- life cycle ---------------------------------------------------------------
    def start(self) -> Ros1Bridge:
        """Probe the master, start the rospy process and wait for its node to register
        (blocks: await :meth:`__aenter__` from a loop)."""
        if self.node is not None:
            return self
        if self._closed:
            raise RosError("this Ros1Bridge was closed; make a new one")
        probe_master(self.master_uri)
        ours, theirs = socket.socketpair()
        for end in (ours, theirs):  # blocking, whatever socket.setdefaulttimeout says
            end.setblocking(True)  # (rospy sets one: its fd would be non-blocking)
        env = dict(os.environ, ROS_MASTER_URI=self.master_uri, ROS_NAMESPACE=self.namespace)
        child = "btcap.ros.child1"
        try:
            with theirs:
                self.process = subprocess.Popen(
                    [sys.executable, "-m", child, str(theirs.fileno()), self.settings.node_name],
                    pass_fds=(theirs.fileno(),),
                    env=env,
                    stdin=subprocess.DEVNULL,
                )
            self._sock = ours
            self._outbox = Outbox(ours, f"btcap-ros1-writer{self.fqn}")
            conn = self._conn = Connection(os.dup(ours.fileno()))
            if not conn.poll(START_S):
                raise RosError(f"ROS 1 node {self.fqn}: not up within {START_S} s")
            up = wire1.decode_up(conn.recv_bytes())
            if not isinstance(up, wire1.Up) or up.error:
                why = up.error if isinstance(up, wire1.Up) else f"unexpected {up!r}"
                raise RosError(f"ROS 1 node {self.fqn} on {self.master_uri}: {why}")
        except BaseException as exc:
            self.close()
            if isinstance(exc, EOFError | OSError):
                raise RosError(f"ROS 1 node {self.fqn}: its process ended at start") from None
            raise
        self.node = Node1(self)
        self._reader = threading.Thread(target=self._read, name=f"btcap-ros1{self.fqn}")
        self._reader.start()
        return self

    @property
    def domain_id(self) -> int:
        return -1

    def close(self) -> None:
        """Have the rospy process cancel the open goals, unregister from the master and
        exit; reap it and join the reader. Idempotent."""
        if self._closed:
            return
        self._closed = True
        process, conn, outbox = self.process, self._conn, self._outbox
        if outbox is not None:
            with contextlib.suppress(RosError):  # the process is gone already
                self.send(wire1.Stop())
        if process is not None:
            try:
                process.wait(timeout=STOP_S)
            except subprocess.TimeoutExpired:
                log.warning("btcap.ros1.kill", node=self.fqn, why=f"no exit in {STOP_S} s")
                process.kill()
                process.wait()
        if outbox is not None:  # the process is gone: what it did not read fails at once
            outbox.close(timeout=STOP_S)
        if self._reader is not None:
            self._reader.join(timeout=STOP_S)
        if conn is not None:
            conn.close()
        if self._sock is not None:
            self._sock.close()
        self._lost("the bridge closed")
        self.node = None

    def running(self) -> Any:
        if self._dead is not None and not self._closed:
            raise RosError(f"ROS 1 bridge {self.fqn}: {self._dead}")
        return super().running()

    # -- frames ---------------------------------------------------------------------
    def next_id(self) -> int:
        return next(self._ids)

    def send(self, frame: wire1.Down) -> None:
        """Send one frame to the rospy process, never waiting for it (from any thread:
        :class:`~btcap.ros.outbox1.Outbox`); a publisher's messages waiting beyond its
        queue size are dropped, oldest first, as rospy's own queue does."""
        outbox = self._outbox
        if outbox is None or self._dead is not None:
            raise RosError(f"ROS 1 bridge {self.fqn}: {self._dead or 'not started'}")
        cid = frame.cid if isinstance(frame, wire1.Publish) else None
        try:
            outbox.put(wire1.encode(frame), cid, self._depths.get(cid or 0, 0))
        except OSError as exc:
            raise RosError(f"ROS 1 bridge {self.fqn}: its process is gone ({exc})") from None

    def open(
        self, kind: str, type_name: str, name: str, qos: tuple[int, bool] = (10, False)
    ) -> int:
        cid = self.next_id()
        self.running()
        if kind == "publisher":
            self._depths[cid] = qos[0]
        self.send(wire1.Open(cid, kind, type_name, name, qos[0], qos[1]))
        return cid

    def drop(self, cid: int) -> None:
        self._servers.pop(cid, None)
        self._labels.pop(cid, None)
        self._subs.pop(cid, None)
        self._depths.pop(cid, None)
        if self._dead is None and not self._closed:
            self.send(wire1.Drop(cid))

    def open_goal(self, handle: GoalHandle1) -> None:
        self._handles[handle.gid] = handle

    def call(self, client: ServiceClient1, data: bytes) -> Future1:
        future, qid = Future1(), self.next_id()
        self._calls[qid] = (future, client.types)
        self.send(wire1.Call(client.cid, qid, data))
        return future

    def forget_call(self, future: Future1) -> None:
        for qid, (f, _) in list(self._calls.items()):
            if f is future:
                del self._calls[qid]

    def subscribe(
        self, sub: Subscription1, type_name: str, name: str, qos: tuple[int, bool]
    ) -> None:
        self._subs[sub.cid] = sub
        self.running()
        self.send(wire1.Open(sub.cid, "subscriber", type_name, self.resolve(name), *qos))

    def _read(self) -> None:  # the reader thread
        conn = self._conn
        assert conn is not None
        while True:
            try:
                frame = wire1.decode_up(conn.recv_bytes())
            except (EOFError, OSError):
                break
            try:
                self._dispatch(frame)
            except Exception as exc:  # a node's callback failed: log it, keep reading
                log.error(
                    "btcap.ros1.frame", node=self.fqn, frame=type(frame).__name__, why=str(exc)
                )
        if not self._closed and self.conflict is None:
            # Not closing: it crashed or was killed. Every ROS node of the robot fails
            # now saying so (their servers would otherwise just look gone).
            code: int | None = None
            with contextlib.suppress(subprocess.TimeoutExpired, AttributeError):
                code = self.process.wait(timeout=1.0)  # type: ignore[union-attr]
            self.conflict = (
                f"the ROS 1 node {self.fqn}'s rospy process ended unasked (exit code {code})"
                + _RESTART
            )
            log.error("btcap.ros1.process_ended", node=self.fqn, code=code)
        self._lost("its rospy process ended")

    def _dispatch(self, frame: Any) -> None:
        """Hand a frame to what waits on it; the nodes' own callbacks wake the tree (as
        they do on ROS 2), so this never does."""
        if isinstance(frame, wire1.Feedback):
            handle = self._handles.get(frame.gid)
            if handle is not None:
                handle.on_feedback(frame.data)
        elif isinstance(frame, wire1.Message):
            sub = self._subs.get(frame.cid)
            if sub is not None:
                sub.on_message(frame.data)
        elif isinstance(frame, wire1.Ready):
            server = self._servers.get(frame.cid)
            if server is not None:
                server.ready = frame.ready
        elif isinstance(frame, wire1.Accepted):
            handle = self._handles.get(frame.gid)
            if handle is not None:
                handle.on_accepted()
        elif isinstance(frame, wire1.Done):
            handle = self._handles.pop(frame.gid, None)
            if handle is not None:
                handle.on_done(frame)
        elif isinstance(frame, wire1.Reply):
            call = self._calls.pop(frame.qid, None)
            if call is not None:
                future, types = call
                if frame.error:
                    future.set(exception=RosError(frame.error))
                else:
                    future.set(types.Response().deserialize(frame.data))
        elif isinstance(frame, wire1.Mismatch):
            client = self._servers.get(frame.cid) or self._subs.get(frame.cid)
            if client is not None:
                client.mismatch = frame.found or None
        elif isinstance(frame, wire1.Notice):
            log.warning("btcap.ros1.notice", node=self.fqn, why=frame.text)
        elif isinstance(frame, wire1.Up) and frame.error and not self._closed:
            self.conflict = f"the ROS 1 node {self.fqn} was shut down: {frame.error}"
            log.error("btcap.ros1.shutdown", node=self.fqn, why=frame.error)

    def _lost(self, why: str) -> None:
        """The rospy process is gone: fail what waits on it."""
        if self._dead is None:
            self._dead = why
        for server in list(self._servers.values()):
            server.ready = False
        handles, self._handles = list(self._handles.values()), {}
        calls, self._calls = list(self._calls.values()), {}
        for handle in handles:
            handle.on_lost(f"the ROS 1 bridge {self.fqn}: {why}")
        for future, _ in calls:
            future.set(exception=RosError(f"the ROS 1 bridge {self.fqn}: {why}"))
        if handles or calls:
            self.wake()

    # -- what nodes use -----------------------------------------------------------
    def qos(self, qos: Qos | None = None) -> tuple[int, bool]:
        """ROS 1 has no QoS: a topic's queue size (``depth``) and whether it latches
        (``durability: transient_local``)."""
        q = qos if qos is not None else self.settings.qos
        return q.depth, q.durability == "transient_local"

    def action_client(self, type_name: str, name: str) -> Any:
        key = ("action", type_name, self.resolve(name))
        client = self._clients.get(key)
        if client is None:
            types = interface1(type_name, "action")
            cid = self.next_id()
            client = self._clients[key] = self._servers[cid] = ActionClient1(self, cid, types)
            self._labels[cid] = (f"action {key[2]}", type_name)
            self.running()
            self.send(wire1.Open(cid, "action", type_name, key[2]))
        return client

    def subscription_events(self, topic: str, on_incompatible: Any = None) -> dict[str, Any]:
        return {}  # ROS 1 has no QoS to disagree on

    def mismatch(self, client: Any, asker: str = "", effect: str = "") -> str | None:
        """The type ``client``'s peer has, as the rospy process last found it
        (:mod:`btcap.ros.peers1`), when another than the client's own. With ``effect``
        (what that does to ``asker``: a bid, a cost), ``asker`` is told once per type, as
        on ROS 2; a node fails saying it instead."""
        found: str | None = getattr(client, "mismatch", None)
        if found is not None and effect:
            cid = client.cid
            key = (asker, cid, found)
            if key not in self._told and cid in self._labels:
                if len(self._told) >= _TOLD:
                    self._told.clear()  # (a line again now and then, never unbounded)
                self._told.add(key)
                what, expected = self._labels[cid]
                tell(asker, what, expected, found, effect)
        return found

    def server_ready(
        self, kind: str, type_name: str, name: str, asker: str = "", effect: str = ""
    ) -> bool:
        """As :meth:`RosBridge.server_ready`; a server the rospy process found to have
        another type is not ready (a service's probe connects to it all the same)."""
        if kind == "action":
            client = self.action_client(type_name, name)
        else:
            client = self.service_client(type_name, name)
        return self.mismatch(client, asker, effect) is None and bool(client.ready)

    def send_goal(self, client: Any, goal: Any, feedback: Any) -> tuple[Any, Any]:
        handle = client.send_goal(goal, feedback_callback=feedback)
        return handle.response, handle

    def halt_goal(self, key: Any) -> bool:
        """Cancel goal ``key`` (its GoalHandle1) now, accepted or not (actionlib recalls a
        goal whose cancel comes before it), and forget it here: nothing of it is news to
        the node any more, and a goal whose server died would never end, holding the
        node and its tree. The rospy process keeps it, to cancel again when closing."""
        if self._handles.pop(key.gid, None) is not None:
            with contextlib.suppress(RosError):  # the process is gone: it cancelled its goals
                self.send(wire1.Cancel(key.gid))
        return True

    def service_client(self, type_name: str, name: str) -> Any:
        key = ("service", type_name, self.resolve(name))
        client = self._clients.get(key)
        if client is None:
            types = interface1(type_name, "srv")
            cid = self.next_id()
            client = self._clients[key] = self._servers[cid] = ServiceClient1(self, cid, types)
            self._labels[cid] = (f"service {key[2]}", type_name)
            self.running()
            self.send(wire1.Open(cid, "service", type_name, key[2]))
        return client

    def latest(self, type_name: str, topic: str) -> tuple[Any, float] | None:
        """As :meth:`RosBridge.latest`: before the first message, a topic published only
        with another type is told once."""
        key = (type_name, self.resolve(topic))
        box = self._latest.get(key)
        if box is None:
            import time

            box = [None]

            def store(message: Any, box: list[Any] = box) -> None:  # the reader thread
                box[0] = (message, time.monotonic())

            cls = interface1(type_name, "msg")
            box.append(self.running().create_subscription(cls, key[1], store, self.qos()))
            self._labels[box[1].cid] = (f"topic {key[1]}", type_name)
            self._latest[key] = box
        if box[0] is None:
            self.mismatch(box[1], f"RosBridge {self.fqn} (a cost reads it)", _UNREAD)
        latest: tuple[Any, float] | None = box[0]
        return latest
