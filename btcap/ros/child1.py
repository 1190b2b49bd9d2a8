"""A robot's rospy process: one ROS 1 node, driven by its bridge (:mod:`btcap.ros.client1`)
over a pipe of :mod:`btcap.ros.wire1` frames.

rospy allows one ``init_node`` per process and runs its callbacks on threads of its own,
so each robot's ROS 1 side lives here, in a child process, and the agent's process never
imports rospy's node machinery. The main thread reads the bridge's frames and acts on them
(rospy's publish and actionlib's ``send_goal`` do not block). rospy's threads write a
goal's acceptance and end and a call's reply at once (a thread handoff more would cost
each round trip); feedback and topic messages go through a writer thread, which keeps just
the latest of a goal or topic while earlier ones wait, so a flood costs the pipe at most
one frame per write and never holds rospy's thread. A poller thread checks each action
and service server and reports its availability on change, by the rule of
:mod:`btcap.ros.availability` (one failed check under load does not make a server gone),
and, for a client that found no peer, a peer of another type (:mod:`btcap.ros.peers1`).
``Stop`` (or the pipe closing: the agent is gone) cancels the open goals, unregisters
every publisher, subscriber and client from the master, and exits.

Run as ``python -m btcap.ros.child1 FD NODE_NAME`` with ``ROS_MASTER_URI`` and
``ROS_NAMESPACE`` set; FD is the child's end of the bridge's socket pair.
"""

from __future__ import annotations

import contextlib
import io
import queue
import socket
import sys
import threading
import time
from multiprocessing.connection import Connection
from typing import Any

from btcap.ros import rpc1, wire1
from btcap.ros.availability import Availability
from btcap.ros.interfaces1 import interface1
from btcap.ros.peers1 import PeerTypes

__all__ = ["main"]

#: How often the poller looks at action servers (their connections, a local check) and
#: services (a master lookup and a probe connection, as rospy's wait_for_service does).
ACTION_POLL_S = 0.02
SERVICE_POLL_S = 0.1
#: How often it asks the master its pid (a new one: the master restarted).
MASTER_POLL_S = 1.0
#: How often it asks the types of the publishers that action clients without a server
#: and subscribers without a publisher wait on (btcap.ros.peers1) ...
TYPES_POLL_S = 0.2
#: ... and those of the clients connected to one (another type beside it is noted).
PEERS_POLL_S = 2.0
#: How long a call to the master may take (btcap.ros.rpc1): it answers in milliseconds.
MASTER_CALL_S = 1.0
#: How long closing waits for the servers to acknowledge the open goals' cancels.
CANCEL_ACK_S = 5.0
_KINDS = {"action": "action", "service": "srv", "publisher": "msg", "subscriber": "msg"}


def _bytes(message: Any) -> bytes:
    buf = io.BytesIO()
    message.serialize(buf)
    return buf.getvalue()


class Child:
    """The node's clients, goals and the threads around them."""

    def __init__(self, conn: Connection) -> None:
        import actionlib
        import rospy

        self.rospy = rospy
        self.actionlib = actionlib
        self.conn = conn
        self.clients: dict[int, tuple[str, Any, Any]] = {}  # cid -> (kind, types, client)
        self.names: dict[int, str] = {}  # cid -> its resolved name
        self.peers = PeerTypes(rospy.get_name(), self.ask)
        self._silent = False  # the master's last call timed out (said once)
        self.up = False  # Up was sent: the bridge reads notices from then on
        self.goals: dict[int, tuple[Any, Any]] = {}  # gid -> (ClientGoalHandle, its client)
        self.ready: dict[int, bool] = {}
        self.availability: dict[int, Availability] = {}
        self.lock = threading.Lock()
        self._send = threading.Lock()
        self._out: queue.SimpleQueue[Any] = queue.SimpleQueue()
        self._latest: dict[tuple[str, int], Any] = {}
        self._stopping = threading.Event()
        self._writer = threading.Thread(target=self._writer_loop, name="btcap-ros1-writer")
        self._poller = threading.Thread(target=self._poll, name="btcap-ros1-poller", daemon=True)
        self.master_pid: int | None = None

    # -- frames out (any thread) --------------------------------------------------------
    def post(self, frame: Any, flush: tuple[str, int] | None = None) -> None:
        """Write ``frame`` now, after the frame of key ``flush`` still waiting, if any (a
        goal's last feedback goes before its end)."""
        with self._send:
            if flush is not None:
                with self.lock:
                    waiting = self._latest.pop(flush, None)
                if waiting is not None:
                    self._write(waiting)
            self._write(frame)

    def post_latest(self, key: tuple[str, int], frame: Any) -> None:
        """Have the writer thread send ``frame``, replacing one of the same key not yet
        sent: a flood costs one frame per write, and rospy's thread never waits on it."""
        with self.lock:
            fresh = key not in self._latest
            self._latest[key] = frame
        if fresh:
            self._out.put(key)

    def _write(self, frame: Any) -> None:
        with contextlib.suppress(OSError):  # the bridge is gone: the main thread sees EOF
            self.conn.send_bytes(wire1.encode(frame))

    def _writer_loop(self) -> None:
        while True:
            key = self._out.get()
            if key is None:
                return
            with self._send:
                with self.lock:
                    frame = self._latest.pop(key, None)
                if frame is not None:
                    self._write(frame)

    # -- readiness -------------------------------------------------------------------
    def _poll(self) -> None:
        last_services = last_master = last_types = last_peers = 0.0
        while not self._stopping.wait(ACTION_POLL_S):
            t = time.monotonic()
            services = t - last_services >= SERVICE_POLL_S
            if services:
                last_services = t
            if t - last_master >= MASTER_POLL_S:
                last_master = t
                self._check_master()
            types = t - last_types >= TYPES_POLL_S
            if types:
                last_types = t
                self.peers.new_round()
            peers = types and t - last_peers >= PEERS_POLL_S
            if peers:
                last_peers = t
            for cid, (kind, cls, client) in list(self.clients.items()):
                if kind == "action":
                    ok = _action_ready(client)
                    if types:
                        self._check_type(cid, kind, cls, ok, peers)
                elif kind == "service" and services:
                    ok = self._service_ready(cid, cls, client.resolved_name)
                else:
                    if kind == "subscriber" and types:
                        self._check_type(cid, kind, cls, _publisher_connected(client), peers)
                    continue
                ready = self.availability.setdefault(cid, Availability()).check(
                    ok, time.monotonic()
                )
                if self.ready.get(cid) != ready:
                    self.ready[cid] = ready
                    self.post(wire1.Ready(cid, ready))

    def ask(self, method: str, *args: Any) -> Any:
        """The value of master call ``method`` (this node's name first, then ``args``),
        within MASTER_CALL_S, else RosCallError; the first call of a stall (a master that
        took the connection and did not answer: nothing else would say so) tells the
        bridge, in one line naming the master and the call."""
        import rosgraph

        try:
            value = rpc1.call(
                rosgraph.get_master_uri(),
                method,
                self.rospy.get_name(),
                *args,
                timeout_s=MASTER_CALL_S,
            )
        except rpc1.RosCallError as exc:
            if exc.stalled and not self._silent and self.up:
                self._silent = True
                self.post(
                    wire1.Notice(
                        f"{exc} (until it answers, this robot's services count as gone "
                        "and its peers' types are unknown)"
                    )
                )
            raise
        self._silent = False
        return value

    def ask_master_pid(self) -> int | None:
        """The master's pid, or None if it does not answer now."""
        try:
            return int(self.ask("getPid"))
        except (rpc1.RosCallError, TypeError, ValueError):
            return None

    def _check_master(self) -> None:
        """Tell the bridge once the master restarted (its pid changed): ROS 1 nodes never
        register again, so what was registered before is unknown to the new one."""
        pid = self.ask_master_pid()
        if pid is None:  # gone for now: its services' checks say so
            return
        import rosgraph

        uri = rosgraph.get_master_uri()
        if self.master_pid is not None and pid != self.master_pid:
            self.post(
                wire1.Notice(
                    f"the ROS 1 master {uri} restarted (pid {self.master_pid}, now {pid}): it "
                    "knows nothing registered before, and ROS 1 nodes do not register again, "
                    "so the servers and topics of nodes started before it (this robot's "
                    "too) stay unknown to it until those nodes restart"
                )
            )
        self.master_pid = pid

    def _check_type(self, cid: int, kind: str, types: Any, connected: bool, peers: bool) -> None:
        """An action client's or subscriber's peers: the types of each (a client
        ``connected`` to one has its type: its others only noted, looked at if ``peers``)."""
        if connected and not peers:
            self._found(cid, "")
            return
        found, noted = self.peers.check(kind, types, self.names.get(cid, ""), connected)
        self._found(cid, found)
        if self.peers.note(cid, noted) and noted:
            self.post(wire1.Notice(noted))

    def _found(self, cid: int, found: str) -> None:
        """Tell the bridge when what client ``cid``'s peer is typed as changes (before its
        readiness: a node reads the mismatch first)."""
        if self.peers.news(cid, found):
            self.post(wire1.Mismatch(cid, found))

    def _service_ready(self, cid: int, types: Any, name: str) -> bool:
        import rosgraph.network

        rospy = self.rospy
        try:
            uri = str(self.ask("lookupService", name))
            host, port = rospy.core.parse_rosrpc_uri(uri)
            with socket.create_connection((host, port), timeout=0.5) as s:
                header = {
                    "probe": "1",
                    "md5sum": "*",
                    "callerid": rospy.get_name(),
                    "service": name,
                }
                rosgraph.network.write_ros_handshake_header(s, header)
                self._found(cid, self.peers.service(types, uri, s))
        except Exception:  # not registered, or registered by a process that is gone
            return False
        return True

    # -- frames in (main thread) -------------------------------------------------------
    def serve(self) -> None:
        self._writer.start()
        self._poller.start()
        try:
            while True:
                try:
                    frame = wire1.decode_down(self.conn.recv_bytes())
                except (EOFError, OSError):
                    return
                if isinstance(frame, wire1.Stop):
                    return
                try:
                    self._handle(frame)
                except Exception as exc:  # a bad frame must not end the robot's ROS side
                    self.rospy.logerr("btcap: %s: %s", type(frame).__name__, exc)
        finally:
            self.stop()

    def _handle(self, frame: wire1.Down) -> None:
        if isinstance(frame, wire1.Publish):
            _, types, pub = self.clients[frame.cid]
            pub.publish(types().deserialize(frame.data))
        elif isinstance(frame, wire1.Goal):
            self._send_goal(frame)
        elif isinstance(frame, wire1.Cancel):
            goal = self.goals.get(frame.gid)
            if goal is not None:
                goal[0].cancel()
        elif isinstance(frame, wire1.Call):
            threading.Thread(target=self._call, args=(frame,), daemon=True).start()
        elif isinstance(frame, wire1.Open):
            self._open(frame)
        elif isinstance(frame, wire1.Drop):
            entry = self.clients.pop(frame.cid, None)
            self.names.pop(frame.cid, None)
            self.ready.pop(frame.cid, None)
            self.availability.pop(frame.cid, None)
            self.peers.forget(frame.cid)
            if entry is not None:
                _unregister(*entry)

    def _open(self, frame: wire1.Open) -> None:
        rospy = self.rospy
        types = interface1(frame.type_name, _KINDS[frame.kind])
        client: Any
        if frame.kind == "action":
            client = self.actionlib.ActionClient(frame.name, types.Action)
        elif frame.kind == "service":
            client = rospy.ServiceProxy(frame.name, types.Service)
        elif frame.kind == "publisher":
            client = rospy.Publisher(frame.name, types, queue_size=frame.depth, latch=frame.latch)
        else:
            cid = frame.cid

            def on_message(message: Any) -> None:  # rospy's thread
                self.post_latest(("m", cid), wire1.Message(cid, _bytes(message)))

            client = rospy.Subscriber(frame.name, types, on_message, queue_size=frame.depth)
        self.names[frame.cid] = frame.name
        self.clients[frame.cid] = (frame.kind, types, client)

    def _send_goal(self, frame: wire1.Goal) -> None:
        _, types, client = self.clients[frame.cid]
        gid = frame.gid
        accepted = [False]
        comm = self.actionlib.CommState

        def on_transition(handle: Any) -> None:  # rospy's thread
            state = handle.get_comm_state()
            if state == comm.DONE:
                with self.lock:
                    self.goals.pop(gid, None)
                result = handle.get_result()
                data = _bytes(result) if result is not None else b""
                status = handle.get_goal_status()
                done = wire1.Done(gid, status, handle.get_goal_status_text(), data)
                self.post(done, flush=("f", gid))
            elif state in (comm.ACTIVE, comm.PREEMPTING) and not accepted[0]:
                accepted[0] = True
                self.post(wire1.Accepted(gid))

        def on_feedback(handle: Any, feedback: Any) -> None:  # rospy's thread
            self.post_latest(("f", gid), wire1.Feedback(gid, _bytes(feedback)))

        goal = types.Goal().deserialize(frame.data)
        with self.lock:
            self.goals[gid] = (client.send_goal(goal, on_transition, on_feedback), client)

    def _call(self, frame: wire1.Call) -> None:
        _, types, proxy = self.clients[frame.cid]
        try:
            response = proxy.call(types.Request().deserialize(frame.data))
        except Exception as exc:  # the service failed, or went away mid-call
            text = str(exc).strip().splitlines()
            self.post(wire1.Reply(frame.qid, error=text[0] if text else type(exc).__name__))
            return
        self.post(wire1.Reply(frame.qid, _bytes(response)))

    @property
    def stopping(self) -> bool:
        return self._stopping.is_set()

    def stop(self) -> None:
        """Cancel open goals, unregister everything, leave the master, flush, end the
        writer."""
        self._stopping.set()
        with self.lock:
            goals = list(self.goals.values())
            self.goals.clear()
        for handle, _ in goals:
            with contextlib.suppress(Exception):  # the publisher is gone: nothing to cancel
                handle.cancel()
        # The cancels leave on rospy's publisher threads: unregistering before the servers
        # acknowledged them could drop them. Wait (a bound) for each still-reachable one.
        waiting = self.actionlib.CommState.WAITING_FOR_CANCEL_ACK
        deadline = time.monotonic() + CANCEL_ACK_S
        while goals and time.monotonic() < deadline:
            goals = [(h, c) for h, c in goals if h.get_comm_state() == waiting and _action_ready(c)]
            time.sleep(0.01)
        for entry in self.clients.values():
            _unregister(*entry)
        self.clients.clear()
        self.rospy.signal_shutdown("btcap: the robot's ROS 1 bridge closed")
        self._poller.join(timeout=2.0)
        self._out.put(None)
        self._writer.join(timeout=2.0)


def _unregister(kind: str, types: Any, client: Any) -> None:
    if kind == "action":
        client.stop()
    elif kind == "service":
        client.close()
    else:
        client.unregister()


def _publisher_connected(subscriber: Any) -> bool:
    impl = subscriber.impl
    return impl is not None and bool(impl.connections)


def _action_ready(client: Any) -> bool:
    """actionlib's ``wait_for_server`` test, once and without waiting: the server's status
    came, and its goal, cancel, result and feedback connections are up."""
    status = client.last_status_msg
    if status is None:
        return False
    server = status._connection_header["callerid"]
    if not (
        client.pub_goal.impl.has_connection(server)
        and client.pub_cancel.impl.has_connection(server)
    ):
        return False
    return all(
        any(c.callerid_pub == server for c in sub.impl.connections)
        for sub in (client.result_sub, client.feedback_sub)
    )


def main(argv: list[str]) -> int:
    fd, node_name = int(argv[0]), argv[1]
    conn = Connection(fd)
    try:
        import rospy

        rospy.init_node(node_name, anonymous=False, disable_signals=True)
        child = Child(conn)
    except BaseException as exc:
        text = str(exc).strip().splitlines()
        conn.send_bytes(wire1.encode(wire1.Up(error=text[0] if text else repr(exc))))
        return 1
    child.master_pid = child.ask_master_pid()  # now: it may restart before the first check
    child.post(wire1.Up())
    child.up = True

    def on_shutdown(reason: str) -> None:  # rospy's thread: the master, or our own stop
        if not child.stopping:
            child.post(wire1.Up(error=reason))

    rospy.core.add_preshutdown_hook(on_shutdown)
    child.serve()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
