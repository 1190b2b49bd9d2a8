"""Sim leaves: robot-side (drive, operate) and mission-side (claim the next piece of work).

Each runs its request in the background (a tick never waits) and reports RUNNING until
the simulation or the store answers.
"""

from __future__ import annotations

import asyncio
import math
from typing import Any, ClassVar

from btcap import Leaf, Port, State
from btcap.actors import ActorError
from btcap.bt.state import TreeError
from btcap.sim.world.messages import Claim, ClaimReply, MoveTo, Operate, SimResult, StopRobot
from btcap.transports import Address

__all__ = ["ClaimWork", "MoveToLeaf", "OperateLeaf"]

_RUNNING = State.RUNNING
_SUCCEEDED = State.SUCCEEDED
_FAILED = State.FAILED


class _Background(Leaf):
    """A leaf whose tick polls one background request.

    The answer is kept until reset, so a reactive parent re-ticking the leaf does not
    repeat the request.
    """

    __slots__ = ("_answer", "_task")

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self._task: asyncio.Task[Any] | None = None
        self._answer: Any = None
        super().__init__(*args, **kwargs)

    def _ref_to(self, where: str) -> Any:
        system = self.tree.system
        if system is None:
            raise TreeError(f"{self.path!r} needs its tree attached to a robot's actor system")
        return system.ref(Address.parse(where) if "/" in where else where)

    def _limit(self, seconds: float) -> float:
        """An ask's timeout covering ``seconds`` of clock time with a margin: wall
        seconds on a real clock, clock seconds on a virtual one (as the ask counts)."""
        if math.isinf(self.clock.speedup):
            return seconds * 3 + 2.0
        return max(2.0, self.clock.to_wall(seconds) * 3 + 2.0)

    def _poll(self, start: Any) -> Any:
        """Start the request on the first tick; return its result once done, else None."""
        if self._answer is not None:
            return self._answer
        task = self._task
        if task is None:
            self._task = self.start_background(start())
            return None
        if not task.done():
            return None
        self._task = None
        self._answer = task.result()
        return self._answer

    def _cancel(self) -> None:
        if self._task is not None:
            self._task.cancel()
            self._task = None

    def on_untick(self) -> None:
        self._cancel()

    def on_reset(self) -> None:
        self._cancel()
        self._answer = None

    def on_shutdown(self) -> None:
        self._cancel()


class MoveToLeaf(_Background):
    """Drives the robot to ``goal``; fails if the simulation says it cannot."""

    __slots__ = ()
    INPUTS: ClassVar[Any] = {"goal": Port(tuple[int, int] | None, None)}
    OPTIONS: ClassVar[Any] = {"robot": Port(str), "manager": Port(str, "sim/manager")}

    def on_tick(self) -> State:
        goal = self.inputs["goal"]
        if goal is None:
            return _FAILED
        result = self._poll(lambda: self._move(tuple(goal)))
        if result is None:
            return _RUNNING
        return _SUCCEEDED if result.ok else _FAILED

    async def _move(self, goal: tuple[int, int]) -> SimResult:
        ref = self._ref_to(self.options["manager"])
        try:
            result: SimResult = await ref.ask(
                MoveTo(self.options["robot"], goal), expect=SimResult, timeout=self._limit(3600)
            )
        except asyncio.CancelledError:
            ref.tell(StopRobot(self.options["robot"]))
            raise
        except ActorError as exc:  # e.g. no answer in time: the robot must not drive on
            ref.tell(StopRobot(self.options["robot"]))
            return SimResult(False, (0, 0), str(exc))
        return result


class OperateLeaf(_Background):
    """Asks the simulation for ``op`` (explore / identify / decontaminate) on ``target``."""

    __slots__ = ()
    INPUTS: ClassVar[Any] = {"target": Port(int | None, None)}
    OUTPUTS: ClassVar[Any] = {"found": int, "contaminated": bool}
    OPTIONS: ClassVar[Any] = {
        "robot": Port(str),
        "op": Port(str),
        "manager": Port(str, "sim/manager"),
    }

    def declare_ports(self) -> None:
        if self.options["op"] not in ("explore", "identify", "decontaminate"):
            raise TreeError(
                f"{self.name!r}: op {self.options['op']!r}; expected explore, identify or "
                f"decontaminate"
            )

    def on_tick(self) -> State:
        result = self._poll(self._operate)
        if result is None:
            return _RUNNING
        if not result.ok:
            return _FAILED
        self.outputs["found"] = result.found
        self.outputs["contaminated"] = bool(result.contaminated)
        return _SUCCEEDED

    async def _operate(self) -> SimResult:
        target = self.inputs["target"]
        msg = Operate(self.options["robot"], self.options["op"], -1 if target is None else target)
        ref = self._ref_to(self.options["manager"])
        try:
            result: SimResult = await ref.ask(msg, expect=SimResult, timeout=self._limit(3600))
        except asyncio.CancelledError:
            # Abandoned (paused, cancelled, lease lost): the robot must not go on with it,
            # or it would keep holding an object nobody is waiting for.
            ref.tell(StopRobot(self.options["robot"]))
            raise
        except ActorError as exc:
            ref.tell(StopRobot(self.options["robot"]))
            return SimResult(False, (0, 0), str(exc))
        return result


class ClaimWork(_Background):
    """Mission side: claims the next exploration goal or object from the shared store.

    Succeeds with the work in its outputs; RUNNING while there is nothing to do yet but
    the mission is not over; FAILED once there is nothing left at all (ending a loop).
    """

    __slots__ = ("_again_at",)
    OUTPUTS: ClassVar[Any] = {"target": int, "at": tuple[int, int], "identified": bool}
    OPTIONS: ClassVar[Any] = {
        "kind": Port(str, description="goal or object"),
        "store": Port(str, "sim/store"),
        "poll_s": Port(float, 1.0, "clock seconds between claims while waiting"),
    }

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self._again_at = 0.0
        super().__init__(*args, **kwargs)

    def declare_ports(self) -> None:
        if self.options["kind"] not in ("goal", "object"):
            raise TreeError(f"{self.name!r}: kind must be 'goal' or 'object'")

    def on_tick(self) -> State:
        if self._task is None and self.clock.now() < self._again_at:
            return _RUNNING
        reply = self._poll(self._claim)
        if reply is None:
            return _RUNNING
        if reply.status == "ok":
            self.outputs["target"] = reply.target
            self.outputs["at"] = tuple(reply.at)
            self.outputs["identified"] = reply.identified
            return _SUCCEEDED
        if reply.status == "done":
            return _FAILED
        self._answer = None  # nothing yet: ask again after a while
        self._again_at = self.clock.now() + self.options["poll_s"]
        return _RUNNING

    async def _claim(self) -> ClaimReply:
        claimant = f"{self.tree.system.id if self.tree.system else '?'}:{self.path}"
        try:
            reply: ClaimReply = await self._ref_to(self.options["store"]).ask(
                Claim(claimant, self.options["kind"]), expect=ClaimReply, timeout=5.0
            )
        except ActorError:
            return ClaimReply("wait")
        return reply
