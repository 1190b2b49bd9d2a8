"""Ready-made leaves: actions from async callables, conditions, constants, waits, logs.

Write your own leaf by subclassing :class:`~btcap.bt.node.Leaf`; return the module
constants ``SUCCEEDED``/``FAILED``/``RUNNING`` (the same objects as ``State.SUCCEEDED``…,
read faster in a tick)::

    from btcap import FAILED, SUCCEEDED, Leaf, Port, State

    class Battery(Leaf):
        \"\"\"Succeeds while the battery holds enough charge.\"\"\"

        INPUTS = {"level": float}
        OPTIONS = {"minimum": Port(float, 0.2)}

        def on_tick(self) -> State:
            ok = self.inputs["level"] >= self.options["minimum"]
            return SUCCEEDED if ok else FAILED
"""

from __future__ import annotations

import asyncio
import inspect
import operator
from collections.abc import Awaitable, Callable
from typing import Any, ClassVar

from msgspec import Meta

from btcap.bt.node import Leaf
from btcap.bt.ports import Port, check_port, check_value, normalize_ports
from btcap.bt.state import State, TreeError
from btcap.transports.log import get_logger

__all__ = [
    "LOG_LOGGER",
    "Action",
    "AlwaysFailure",
    "AlwaysRunning",
    "AlwaysSuccess",
    "Compare",
    "Condition",
    "Constant",
    "Log",
    "Wait",
]

_SUCCEEDED = State.SUCCEEDED
_FAILED = State.FAILED
_RUNNING = State.RUNNING

#: The ``logging`` logger Log nodes write to (``btcap tree run`` shows it on stderr).
LOG_LOGGER = "btcap.bt.log"

log = get_logger(LOG_LOGGER)


class AlwaysSuccess(Leaf):
    """Succeeds at once."""

    __slots__ = ()

    def on_tick(self) -> State:
        return _SUCCEEDED


class AlwaysFailure(Leaf):
    """Fails at once."""

    __slots__ = ()

    def on_tick(self) -> State:
        return _FAILED


class AlwaysRunning(Leaf):
    """Never finishes."""

    __slots__ = ()

    def on_tick(self) -> State:
        return _RUNNING


class Constant(Leaf):
    """Outputs ``value`` (of ``type``) and succeeds."""

    __slots__ = ()
    OPTIONS: ClassVar[Any] = {"value": Port(Any), "type": Port(Any, Any, "the output's type")}

    def declare_ports(self) -> None:
        t = self.options["type"]
        self.options["value"] = check_value(
            self.options["value"], t, f"node {self.name!r} option 'value'"
        )
        self.output_ports = {"value": Port(t)}

    def on_tick(self) -> State:
        self.outputs["value"] = self.options["value"]
        return _SUCCEEDED


_OPS: dict[str, Callable[[Any, Any], bool]] = {
    "==": operator.eq,
    "!=": operator.ne,
    "<": operator.lt,
    "<=": operator.le,
    ">": operator.gt,
    ">=": operator.ge,
}


class Compare(Leaf):
    """Succeeds if ``a op b`` holds (``op`` one of ==, !=, <, <=, >, >=)."""

    __slots__ = ()
    INPUTS: ClassVar[Any] = {"a": Port(Any, None), "b": Port(Any, None)}
    OPTIONS: ClassVar[Any] = {"op": Port(str, "==")}

    def declare_ports(self) -> None:
        if self.options["op"] not in _OPS:
            raise TreeError(
                f"Compare {self.name!r}: op {self.options['op']!r}; "
                f"expected one of {', '.join(_OPS)}"
            )

    def on_tick(self) -> State:
        ok = _OPS[self.options["op"]](self.inputs["a"], self.inputs["b"])
        return _SUCCEEDED if ok else _FAILED


class Log(Leaf):
    """Logs ``message`` (with the ``value`` input, if wired) and succeeds.

    It logs on the ``logging`` logger :data:`LOG_LOGGER`, which a program shows like any
    other (``btcap tree run`` shows it on stderr).
    """

    __slots__ = ()
    INPUTS: ClassVar[Any] = {"value": Port(Any, None)}
    OPTIONS: ClassVar[Any] = {"message": Port(str), "level": Port(str, "info")}

    def declare_ports(self) -> None:
        if self.options["level"] not in ("debug", "info", "warning", "error"):
            raise TreeError(f"Log {self.name!r}: level must be debug, info, warning or error")

    def on_tick(self) -> State:
        getattr(log, self.options["level"])(
            self.options["message"], node=self.path, value=self.inputs["value"]
        )
        return _SUCCEEDED


class Wait(Leaf):
    """Runs for ``seconds`` of clock time after its first tick, then succeeds."""

    __slots__ = ("_until",)
    OPTIONS: ClassVar[Any] = {"seconds": Port(float, meta=Meta(ge=0))}

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._until: float | None = None

    def on_tick(self) -> State:
        now = self.clock.now()
        if self._until is None:
            self._until = now + self.options["seconds"]
        if now >= self._until:
            self._until = None
            return _SUCCEEDED
        return _RUNNING

    def on_reset(self) -> None:
        self._until = None


class Condition(Leaf):
    """Succeeds when ``predicate(**inputs)`` is true; for quick checks, never I/O."""

    __slots__ = ("_ports_in", "predicate")

    def __init__(
        self,
        predicate: Callable[..., bool],
        name: str | None = None,
        *,
        inputs: dict[str, Any] | None = None,
        **kwargs: Any,
    ) -> None:
        self.predicate = predicate
        self._ports_in = normalize_ports(inputs or {}, f"Condition {name!r} inputs")
        super().__init__(name or getattr(predicate, "__name__", None), **kwargs)

    def declare_ports(self) -> None:
        self.input_ports = self._ports_in

    def on_tick(self) -> State:
        return _SUCCEEDED if self.predicate(**self.inputs) else _FAILED


class Action(Leaf):
    """Runs ``fn(**inputs)`` (an async callable) in the background; running until done.

    The first tick starts it; untick, reset and shutdown cancel it. It succeeds when ``fn``
    returns ``None`` or ``True``, fails on ``False``, and a ``dict`` result fills the
    outputs of the same names (and succeeds). An exception puts the node in ERROR.
    """

    __slots__ = ("_ports_in", "_ports_out", "_task", "fn")

    def __init__(
        self,
        fn: Callable[..., Awaitable[Any]],
        name: str | None = None,
        *,
        inputs: dict[str, Any] | None = None,
        outputs: dict[str, Any] | None = None,
        **kwargs: Any,
    ) -> None:
        if not (inspect.iscoroutinefunction(fn) or callable(fn)):
            raise TypeError(f"Action {name!r}: expected an async callable, got {fn!r}")
        self.fn = fn
        self._task: asyncio.Task[Any] | None = None
        self._ports_in = normalize_ports(inputs or {}, f"Action {name!r} inputs")
        self._ports_out = normalize_ports(outputs or {}, f"Action {name!r} outputs")
        super().__init__(name or getattr(fn, "__name__", None), **kwargs)

    def declare_ports(self) -> None:
        self.input_ports = self._ports_in
        self.output_ports = self._ports_out

    def on_tick(self) -> State:
        task = self._task
        if task is None:
            self._task = self.start_background(self._call(dict(self.inputs)))
            return _RUNNING
        if not task.done():
            return _RUNNING
        self._task = None
        if task.cancelled():
            return _FAILED
        exc = task.exception()
        if exc is not None:
            raise exc
        result = task.result()
        if result is False:
            return _FAILED
        if isinstance(result, dict):
            ports = self.output_ports
            for key, value in result.items():
                port = ports.get(key)
                if port is None:
                    raise TreeError(f"Action {self.name!r} returned unknown output {key!r}")
                where = f"Action {self.name!r} output {key!r}"
                self.outputs[key] = check_port(value, port, where)
        return _SUCCEEDED

    async def _call(self, inputs: dict[str, Any]) -> Any:
        return await self.fn(**inputs)

    def _cancel(self) -> None:
        if self._task is not None:
            self._task.cancel()
            self._task = None

    def on_untick(self) -> None:
        self._cancel()

    def on_reset(self) -> None:
        self._cancel()

    def on_shutdown(self) -> None:
        self._cancel()
