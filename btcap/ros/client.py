"""The robot's ROS 2 client: one rclpy node on an executor thread of its own.

The tree never waits on ROS: nodes call rclpy's non-blocking calls (``send_goal_async``,
``call_async``, ``publish``) from the tick, and rclpy's callbacks run on the bridge's
executor thread, where they store what arrived (a result, the latest feedback or message)
for the next tick to read, and hand the news to the event loop through a
:class:`~btcap.ros.waker.Waker`: the node's tree is ticked soon instead of at its next
period, one hand-over at a time and feedback at most every
:data:`~btcap.ros.waker.FEEDBACK_WAKE_S`, so a 1 kHz feedback stream does not flood the
loop. :meth:`RosBridge.start` (imports, discovery) runs in a worker thread when awaited.
:meth:`RosBridge.close` cancels the goals still open, destroys the node and joins
the thread: nothing of ROS is left running.

Names resolve in the robot's namespace (``navigate_to_pose`` -> ``/husky1/navigate_to_pose``),
as rclpy does for relative names of a node in that namespace; an absolute name is kept.
"""

from __future__ import annotations

import contextlib
import threading
import time
import uuid
from types import TracebackType
from typing import Any, ClassVar

import anyio

from btcap.actors import ActorSystem, Service
from btcap.ros.errors import RosError
from btcap.ros.interfaces import interface
from btcap.ros.loader import load
from btcap.ros.peers import PeerTypes
from btcap.ros.versions import ROS2, Types
from btcap.team.rossettings import Qos, RosSettings, check_namespace
from btcap.transports.log import get_logger

__all__ = ["CLOSE_WAIT_S", "ROS_BRIDGE", "RosBridge"]

log = get_logger(__name__)

#: The service under which a robot's actor system holds its bridge; nodes find it there.
ROS_BRIDGE: Service[RosBridge] = Service("ros-bridge")

#: How long start() watches the graph for another btcap node in its namespace before it
#: returns: DDS discovery takes tens of milliseconds here, at times over 1.5 s on a
#: loaded machine. The executor thread keeps watching for WATCH_S more: a twin seen then
#: makes every ROS node of this robot fail with the reason (``conflict``), logged once.
CLAIM_WAIT_S = 1.5
WATCH_S = 10.0

#: Closing waits at most this long for the servers to answer the goals it cancels (and
#: for the acceptance of goals sent just before, to cancel them then).
CLOSE_WAIT_S = 2.0
#: A halted goal whose cancel got no answer (its server gone) is forgotten this long after.
FORGET_S = 30.0

now = time.monotonic


class RosBridge:
    """One robot's rclpy node, context and executor thread.

    ``RosBridge(settings, robot="husky1")`` joins domain ``settings.domain_id`` as node
    ``/husky1/btcap``. Use ``async with`` (or :meth:`start` and :meth:`close`); give it to
    a tree's actor system with :meth:`provide` so ROS nodes built from files find it.
    """

    #: The interface functions of this bridge's ROS version (ROS 1: client1.Ros1Bridge).
    types: ClassVar[Types] = ROS2

    def __init__(self, settings: RosSettings | None = None, *, robot: str = "") -> None:
        self.settings = settings if settings is not None else RosSettings()
        if self.settings.namespace is None and not robot:
            self.namespace = "/"
        else:
            self.namespace = self.settings.namespace_of(robot)
        #: The robot's name ("" if not given): what a capability's bid is told as.
        self.robot = robot
        self.rclpy: Any = None
        self.node: Any = None
        self._context: Any = None
        self._executor: Any = None
        self._thread: threading.Thread | None = None
        self._clients: dict[tuple[str, str, str], Any] = {}
        self._goals: dict[int, Any] = {}
        self._latest: dict[tuple[str, str], list[Any]] = {}
        self._wake: Any = None
        self._claim: Any = None
        self._watch: Any = None
        self._peers: PeerTypes | None = None
        #: Why this robot must not use ROS (a twin in its namespace), or None.
        self.conflict: str | None = None
        #: Whether news (a goal answered...) ticks the node's tree soon; False: it waits
        #: for the tree's next periodic tick (as before 0.2.0; for measurements).
        self.nudges = True
        self._lock = threading.Lock()
        self._closed = False

    # -- life cycle ---------------------------------------------------------------
    def start(self) -> RosBridge:
        """Load rclpy, join the domain, make the node, start the executor thread (blocks
        for imports and a short graph check: await :meth:`__aenter__` from a loop)."""
        if self.node is not None:
            return self
        if self._closed:
            raise RosError("this RosBridge was closed; make a new one")
        rclpy = self.rclpy = load()
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor

        context = self._context = Context()
        rclpy.init(context=context, domain_id=self.settings.domain_id)
        try:
            self.node = rclpy.create_node(
                self.settings.node_name, namespace=self.namespace, context=context
            )
            self._executor = SingleThreadedExecutor(context=context)
            self._executor.add_node(self.node)
            self._peers = PeerTypes(self.node, self._executor.create_task)
            self._thread = threading.Thread(
                target=self._spin, name=f"btcap-ros{self.fqn}", daemon=True
            )
            self._thread.start()
            self._check_claim()
        except BaseException:
            self.close()
            raise
        return self

    @property
    def fqn(self) -> str:
        """The node's fully qualified name (``/husky1/btcap``)."""
        return f"{self.namespace.rstrip('/')}/{self.settings.node_name}"

    def _spin(self) -> None:
        executor = self._executor
        try:
            executor.spin()
        except Exception:  # the context was shut down under it: closing
            if not self._closed:
                raise

    def _check_claim(self) -> None:
        """RosError if another btcap node holds this namespace: two robots would otherwise
        share one namespace's actions and topics unseen. Each bridge publishes on the
        hidden topic ``NAMESPACE/_btcap_claim`` and counts its publishers in the graph
        (a node of another name, or a non-btcap node named ``btcap``, is no claim)."""
        from builtin_interfaces.msg import Time

        topic = f"{self.namespace.rstrip('/')}/_btcap_claim"
        self._claim = self.node.create_publisher(Time, topic, 1)
        why = (
            f"namespace {self.namespace!r} is already claimed by another btcap node "
            f"({self.fqn!r}) on ROS domain {self.domain_id}; give each robot its own namespace"
        )
        started = time.monotonic()
        while time.monotonic() < started + CLAIM_WAIT_S:
            if self.node.count_publishers(topic) > 1:
                raise RosError(why)
            time.sleep(0.05)

        # A twin refused at its own start holds its claim at most CLAIM_WAIT_S: only one
        # that stays longer is a robot started beside this one, unseen at both starts.
        persist = CLAIM_WAIT_S + 1.0
        since: list[float] = []

        def watch() -> None:  # executor thread: a twin discovered late
            t = time.monotonic()
            if self.node.count_publishers(topic) > 1:
                since[:] = since or [t]
                if t - since[0] >= persist and self.conflict is None:
                    self.conflict = why
                    log.error("btcap.ros.namespace_claimed", namespace=self.namespace, why=why)
            else:
                since.clear()
            if self.conflict is not None or (t > started + WATCH_S and not since):
                self._watch.cancel()

        self._watch = self.node.create_timer(0.25, watch)

    @property
    def domain_id(self) -> int:
        return int(self._context.get_domain_id()) if self._context is not None else -1

    def close(self) -> None:
        """Cancel open goals (waiting for the servers' answers, a goal not accepted yet
        too, at most :data:`CLOSE_WAIT_S`), destroy the node, stop and join the executor
        thread, leave the domain. Idempotent."""
        if self._closed:
            return
        self._closed = True
        if self._thread is not None and self._thread.is_alive():
            self._cancel_goals()
        if self._executor is not None:
            self._executor.shutdown(timeout_sec=2.0)
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        if self.node is not None:
            for (kind, _, _), client in self._clients.items():
                if kind == "action":
                    client.destroy()
                else:
                    self.node.destroy_client(client)
            self._clients.clear()
            self.node.destroy_node()
        if self._context is not None and self._context.ok():
            self.rclpy.shutdown(context=self._context)
        self.node = None

    async def __aenter__(self) -> RosBridge:
        await anyio.to_thread.run_sync(self.start)
        return self

    async def __aexit__(
        self, et: type[BaseException] | None, e: BaseException | None, tb: TracebackType | None
    ) -> None:
        await anyio.to_thread.run_sync(self.close)

    # -- finding it ---------------------------------------------------------------
    def provide(self, system: ActorSystem) -> None:
        """Let the ROS nodes of trees on ``system`` use this bridge."""
        system.services.provide(ROS_BRIDGE, self)

    @staticmethod
    def of(system: ActorSystem | None) -> RosBridge | None:
        return None if system is None else system.services.get(ROS_BRIDGE)

    # -- what nodes use -----------------------------------------------------------
    def running(self) -> Any:
        """The rclpy node; RosError when the bridge is not started, closed, or shares its
        namespace with another robot."""
        if self.conflict is not None:
            raise RosError(f"ROS bridge {self.fqn}: {self.conflict}")
        if self.node is None:
            state = "closed" if self._closed else "not started"
            raise RosError(f"ROS bridge {self.fqn}: {state}")
        return self.node

    def resolve(self, name: str) -> str:
        """``name`` in the robot's namespace (``/husky1/navigate_to_pose``)."""
        if not name:
            raise RosError("empty ROS name: expected an action, service or topic name")
        backend = self.settings.backend
        if name.startswith("/"):
            return check_namespace(name, "ROS name", backend) if name != "/" else name
        if name.startswith("~"):  # private: ROS 1's ~foo, ROS 2's ~/foo
            rest = name[1:].lstrip("/")
            name = f"{self.settings.node_name}/{rest}" if rest else self.settings.node_name
        return check_namespace(f"{self.namespace.rstrip('/')}/{name}", "ROS name", backend)

    def qos(self, qos: Qos | None = None) -> Any:
        """An rclpy QoSProfile from ``qos`` (the settings' default when None)."""
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

        q = qos if qos is not None else self.settings.qos
        reliable, lasting = q.reliability == "reliable", q.durability == "transient_local"
        return QoSProfile(
            depth=q.depth,
            reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
            durability=DurabilityPolicy.TRANSIENT_LOCAL if lasting else DurabilityPolicy.VOLATILE,
        )

    def action_client(self, type_name: str, name: str) -> Any:
        """The (shared) ActionClient of action ``name`` of type ``type_name``."""
        key = ("action", type_name, self.resolve(name))
        client = self._clients.get(key)
        if client is None:
            from rclpy.action import ActionClient

            cls = interface(type_name, "action")
            client = self._clients[key] = ActionClient(self.running(), cls, key[2])
        return client

    def service_client(self, type_name: str, name: str) -> Any:
        """The (shared) service client of ``name`` of type ``type_name``."""
        key = ("service", type_name, self.resolve(name))
        client = self._clients.get(key)
        if client is None:
            cls = interface(type_name, "srv")
            client = self._clients[key] = self.running().create_client(cls, key[2])
        return client

    def server_ready(
        self, kind: str, type_name: str, name: str, asker: str = "", effect: str = ""
    ) -> bool:
        """Whether an action (``kind="action"``) or service server of ``type_name`` answers
        ``name`` now. While none does but one of another type is there, ``asker`` (if
        given: a capability's bid) is told once per type, with ``effect`` (:meth:`mismatch`)."""
        if kind == "action":
            client = self.action_client(type_name, name)
            ready = bool(client.server_is_ready())
        else:
            client = self.service_client(type_name, name)
            ready = bool(client.service_is_ready())
        if not ready and asker:
            self.mismatch(client, asker, effect)
        return ready

    def latest(self, type_name: str, topic: str) -> tuple[Any, float] | None:
        """The latest message of ``topic`` and when it came (``time.monotonic``), or None
        before the first (a publisher of another type is told); subscribed at the first
        call, for as long as the bridge. For cost functions that read a topic (a pose)."""
        key = (type_name, self.resolve(topic))
        box = self._latest.get(key)
        if box is None:
            box = [None]

            def store(message: Any, box: list[Any] = box) -> None:  # executor thread
                box[0] = (message, time.monotonic())

            events = self.subscription_events(key[1])
            cls = interface(type_name, "msg")
            box.append(self.running().create_subscription(cls, key[1], store, self.qos(), **events))
            self._latest[key] = box
        if box[0] is None:
            self.mismatch(box[1], f"RosBridge {self.fqn} (a cost reads it)")
        latest: tuple[Any, float] | None = box[0]
        return latest

    def subscription_events(self, topic: str, on_incompatible: Any = None) -> dict[str, Any]:
        """``create_subscription``'s keyword that reports a publisher of ``topic`` whose
        QoS the subscription does not accept (none of its messages arrive): a warning
        (rclpy's own goes only to its console) and ``on_incompatible(policy)``."""
        from rclpy.event_handler import SubscriptionEventCallbacks
        from rclpy.qos import qos_policy_name_from_kind

        def incompatible(event: Any) -> None:  # executor thread
            policy = str(qos_policy_name_from_kind(event.last_policy_kind))
            log.warning(
                "btcap.ros.incompatible_qos",
                topic=topic,
                policy=policy,
                why="a publisher offers a QoS this subscription does not accept: "
                "none of its messages arrive",
            )
            if on_incompatible is not None:
                on_incompatible(policy)

        return {"event_callbacks": SubscriptionEventCallbacks(incompatible_qos=incompatible)}

    def mismatch(self, client: Any, asker: str = "", effect: str = "") -> str | None:
        """The type of ``client``'s peers if none has its own; tells ``asker`` once per type
        (``peers``), with ``effect`` if given (what that does to it; else its role's)."""
        peers = self._peers
        return None if peers is None or self.node is None else peers.ask(client, asker, effect)

    def wake_on(self, callback: Any, loop: Any = None) -> None:
        """Also call ``callback()`` on the event loop ``loop`` (the running one by default)
        whenever a goal or call answers or an awaited message comes (feedback does not),
        for a program that ticks its trees itself; None stops it. Trees run with
        :meth:`Tree.run <btcap.bt.tree.Tree.run>` (an agent's) need none: the nodes
        nudge their tree."""
        if callback is None:
            self._wake = None
            return
        import asyncio

        target = loop if loop is not None else asyncio.get_running_loop()
        self._wake = (target, callback)

    def wake(self) -> None:
        """From the executor thread: schedule the wake-up callback, if any."""
        wake = self._wake
        if wake is not None:
            loop, callback = wake
            if not loop.is_closed():
                loop.call_soon_threadsafe(callback)

    # -- goals (btcap.ros.action._Goal) ---------------------------------------------
    def send_goal(self, client: Any, goal: Any, feedback: Any) -> tuple[Any, Any]:
        """Send ``goal`` with ``client``: the future of its answer, and the key that
        :meth:`forget_goal` takes (here the goal's id, which this chooses)."""
        from unique_identifier_msgs.msg import UUID

        goal_id = UUID(uuid=list(uuid.uuid4().bytes))
        future = client.send_goal_async(goal, feedback_callback=feedback, goal_uuid=goal_id)
        return future, bytes(goal_id.uuid)

    def halt_goal(self, key: Any) -> bool:
        """Whether halting goal ``key`` was done here, whatever its state (ROS 1); False:
        the node cancels it, once the server accepted it (ROS 2: a cancel before the
        acceptance would find no goal of that id on the server)."""
        return False

    def forget_goal(self, client: Any, key: Any) -> None:
        """Drop what rclpy's ``client`` keeps of a goal that is over without a result
        (rejected, failed): its feedback callback, which holds the node and its tree;
        rclpy drops it only once it has the goal's result."""
        callbacks = getattr(client, "_feedback_callbacks", None)
        if callbacks is not None:
            callbacks.pop(key, None)

    def track(self, goal: Any) -> None:
        """A goal (``btcap.ros.action._Goal``) the server may still run: closing the
        bridge cancels it, once accepted. Halted goals whose server never answered the
        cancel (gone) are forgotten after :data:`FORGET_S`."""
        with self._lock:
            self._goals[id(goal)] = goal
            if len(self._goals) > 64:
                old = now() - FORGET_S
                for k, g in list(self._goals.items()):
                    if g.halted and g.halted_at < old:
                        del self._goals[k]

    def open_goals(self) -> int:
        """How many goals are open (sent, not halted, no result yet)."""
        return sum(not g.halted for g in list(self._goals.values()))

    def untrack(self, goal: Any) -> None:
        with self._lock:
            self._goals.pop(id(goal), None)

    def _cancel_goals(self) -> None:
        """Halt every goal the servers may still run (an unaccepted one is cancelled as
        its acceptance comes) and wait, at most :data:`CLOSE_WAIT_S`, for the servers
        that are there to answer: a goal left running there would have nobody to stop it."""
        with self._lock:
            goals = list(self._goals.values())
        for goal in goals:
            with contextlib.suppress(Exception):  # the server may be gone: nothing to cancel
                goal.halt()
        end = now() + CLOSE_WAIT_S
        while now() < end and any(
            id(g) in self._goals and g.client.server_is_ready() for g in goals
        ):
            time.sleep(0.01)
