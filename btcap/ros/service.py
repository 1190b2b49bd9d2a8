"""RosService: one ROS 2 service call as a tree node (BehaviorTree.ROS2's RosServiceNode).

Inputs are the Request's fields, outputs the Response's. The call goes out with rclpy's
``call_async`` and the response is read at a later tick; ``server_timeout`` bounds both
the wait for the service and the wait for its response, so a missing or slow server fails
the node, saying which.
"""

from __future__ import annotations

from typing import Any, ClassVar

from btcap.bt.ports import NO_DEFAULT, Port, normalize_ports
from btcap.bt.state import State
from btcap.ros.base import RosLeaf, now, seconds

__all__ = ["RosService"]

_RUNNING = State.RUNNING
_SUCCEEDED = State.SUCCEEDED


class RosService(RosLeaf):
    """Calls a ROS 2 service with its inputs; SUCCEEDED with the response in its outputs."""

    __slots__ = ("_future", "_sent_at", "_types")
    KIND: ClassVar[str] = "srv"
    OPTIONS: ClassVar[dict[str, Any]] = {
        "service_type": Port(str, description="e.g. `std_srvs/srv/SetBool`"),
        "service_name": Port(str, description="resolved in the robot's namespace"),
        "server_timeout": seconds("how long to wait for the service and its response", 1.0),
        "wait_for_server_timeout": seconds(
            "how long to wait for the service to appear; null: server_timeout", None
        ),
    }

    def declare_ports(self) -> None:
        types = self.types
        field_types, port_type = types.field_types, types.port_type
        cls = self._types = types.interface(self.options["service_type"], "srv")
        self.input_ports = normalize_ports(
            {
                k: Port(port_type(t) | None, None, f"Request field ({t})")
                for k, t in field_types(cls.Request).items()
            },
            f"{self.name}.inputs",
        )
        self.output_ports = normalize_ports(
            {
                k: Port(port_type(t), NO_DEFAULT, f"Response field ({t})")
                for k, t in field_types(cls.Response).items()
            },
            f"{self.name}.outputs",
        )
        self._future: Any = None
        self._sent_at = 0.0

    def _client(self) -> Any:
        return self.bridge.service_client(
            self.options["service_type"], self.options["service_name"]
        )

    def _what(self) -> str:
        name = self.bridge.resolve(self.options["service_name"])
        return f"service {name} ({self.options['service_type']})"

    def on_tick(self) -> State:
        future = self._future
        if future is None:
            return self._call()
        if future.done():
            self._future = None
            exc = future.exception()
            if exc is not None:
                return self.failed(f"{self._what()}: the call failed: {exc}")
            outputs = self.outputs
            for k, v in self.types.to_plain(future.result()).items():
                outputs[k] = v
            return _SUCCEEDED
        limit = self.options["server_timeout"]
        if now() - self._sent_at > limit:
            self._stop()
            return self.failed(f"{self._what()}: no response within server_timeout {limit} s")
        return _RUNNING

    def _call(self) -> State:
        client = self._client()
        if (missing := self._server_missing(client.service_is_ready())) is not None:
            return missing
        request = self.types.fill(self._types.Request, self.inputs, f"{self._what()} request")
        outputs = self.outputs
        for k in outputs:
            outputs[k] = None
        self._sent_at = now()
        future = self._future = client.call_async(request)
        bridge = self.bridge
        future.add_done_callback(lambda _: bridge.wake())
        return _RUNNING

    def _stop(self) -> None:
        future, self._future = self._future, None
        self._waiting_since = None
        if future is not None and not future.done():
            self._client().remove_pending_request(future)

    def on_untick(self) -> None:
        self._stop()

    def on_reset(self) -> None:
        self._stop()

    def on_shutdown(self) -> None:
        self._stop()
