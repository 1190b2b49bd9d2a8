"""RosService: one ROS 2 service call as a tree node (BehaviorTree.ROS2's RosServiceNode).

Inputs are the Request's fields, outputs the Response's. The call goes out with rclpy's
``call_async`` and the response is read at the tick it brings about (the node's tree is
ticked soon when it comes); ``wait_for_server_timeout`` bounds the wait for the service
to appear and ``server_timeout`` the wait for its response, so a missing or slow server
fails the node, saying which; a server that leaves the graph during the call fails it
then, and one of another type only (no server of the node's type) as soon as it is seen,
before any call. ``service_name`` is read when a call starts.
"""

from __future__ import annotations

from typing import Any, ClassVar

from btcap.bt.ports import NO_DEFAULT, Port, normalize_ports
from btcap.bt.state import State
from btcap.ros.base import RosLeaf, name_input, now, seconds_options

__all__ = ["RosService"]

_RUNNING = State.RUNNING
_SUCCEEDED = State.SUCCEEDED


class RosService(RosLeaf):
    """Calls a ROS 2 service with its inputs; SUCCEEDED with the response in its outputs."""

    __slots__ = ("_client", "_future", "_name", "_sent_at", "_types")
    KIND: ClassVar[str] = "srv"
    NAME_PORT: ClassVar[str] = "service_name"
    INPUTS: ClassVar[dict[str, Any]] = name_input("service_name", "service")
    OPTIONS: ClassVar[dict[str, Any]] = {
        "service_type": Port(str, description="e.g. `std_srvs/srv/SetBool`"),
        **seconds_options("service"),
    }

    def declare_ports(self) -> None:
        cls = self._types = self.types.interface(self.options["service_type"], "srv")
        fields = {
            k: Port(self.types.port_type(t) | None, None, f"Request field ({t})")
            for k, t in self.types.field_types(cls.Request).items()
        }
        self.input_ports = normalize_ports(
            self.with_name_port(fields, f"{self.options['service_type']} Request"),
            f"{self.name}.inputs",
        )
        self.output_ports = normalize_ports(
            {
                k: Port(self.types.port_type(t), NO_DEFAULT, f"Response field ({t})")
                for k, t in self.types.field_types(cls.Response).items()
            },
            f"{self.name}.outputs",
        )
        self._future: Any = None
        self._client: Any = None
        self._name = "?"
        self._sent_at = 0.0

    def _what(self) -> str:
        return f"service {self._name} ({self.options['service_type']})"

    def on_tick(self) -> State:
        future = self._future
        if future is None:
            return self._call()
        if future.done():
            self._future = None
            exc = future.exception()
            if exc is not None:
                kind = self.options["service_type"]
                wrong = self.mismatched(self._client, f"service {self._name}", kind)
                return wrong or self.failed(f"{self._what()}: the call failed: {exc}")
            outputs = self.outputs
            for k, v in self.types.to_plain(future.result()).items():
                outputs[k] = v
            return _SUCCEEDED
        limit = self.options["server_timeout"]
        if now() - self._sent_at > limit:
            self._stop()
            return self.failed(f"{self._what()}: no response within server_timeout {limit} s")
        # As RosAction's goal: no answer will come. (ROS 1's call fails by itself when its
        # connection breaks, sooner than its readiness, checked every 100 ms, says so.)
        if self.types.version != 1 and not self._client.service_is_ready():
            self._stop()
            return self.failed(f"{self._what()}: the server left during the call")
        return _RUNNING

    def _call(self) -> State:
        name = self._name = self.ros_name()
        kind = self.options["service_type"]
        client = self._client = self.bridge.service_client(kind, name)
        ready = client.service_is_ready()
        # ROS 2 finds a server of another type not ready; ROS 1's probe connects to it.
        if (not ready or self.types.version == 1) and (
            wrong := self.mismatched(client, f"service {name}", kind)
        ) is not None:
            return wrong
        if (missing := self._server_missing(ready, name)) is not None:
            return missing
        fields = {k: v for k, v in self.inputs.items() if k != "service_name"}
        request = self.types.fill(self._types.Request, fields, f"{self._what()} request")
        outputs = self.outputs
        for k in outputs:
            outputs[k] = None
        self._sent_at = now()
        future = self._future = client.call_async(request)
        news = self.news()
        future.add_done_callback(lambda _: news(False))
        return _RUNNING

    def _stop(self) -> None:
        future, self._future = self._future, None
        self._waiting_since = None
        if future is not None and not future.done():
            self._client.remove_pending_request(future)

    def on_untick(self) -> None:
        self._stop()

    def on_reset(self) -> None:
        self._stop()

    def on_shutdown(self) -> None:
        self._stop()
