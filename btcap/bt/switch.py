"""Switch: the child whose case equals an input runs (btcap's own, and BehaviorTree.CPP's
``Switch2``…``Switch6`` through the XML loader)."""

from __future__ import annotations

from typing import Any, ClassVar

from btcap.bt.composites import Composite, collapse, halt_active
from btcap.bt.node import Node
from btcap.bt.ports import Port
from btcap.bt.state import State, TreeError
from btcap.bt.utility import Utility, fallback_utility

__all__ = ["Switch"]

_FAILED = State.FAILED


class Switch(Composite):
    """Ticks the child whose case equals the ``value`` input; the last child is the default.

    ``cases`` lists one value per child (``len(cases) == len(children)``) or one fewer,
    in which case the last child runs when no case matches; otherwise no match fails.
    """

    __slots__ = ("_active",)
    INPUTS: ClassVar[Any] = {"value": Port(Any, None, "the value to switch on")}
    OPTIONS: ClassVar[Any] = {"cases": Port(list[Any], description="one value per child")}

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._active: Node | None = None

    def check_children(self) -> None:
        n, k = len(self.children), len(self.options["cases"])
        if k not in (n, n - 1):
            raise TreeError(
                f"Switch {self.name!r}: {k} cases for {n} children; expected {n} or {n - 1}"
            )

    def on_setup(self) -> None:
        self.check_children()

    def on_tick(self) -> State:
        value = self.inputs["value"]
        cases: list[Any] = self.options["cases"]
        children = self.children
        try:
            chosen: Node | None = children[cases.index(value)]
        except ValueError:
            chosen = children[-1] if len(cases) < len(children) else None
        if self._active is not None and self._active is not chosen:
            halt_active(self._active)
        self._active = chosen
        if chosen is None:
            return _FAILED
        return collapse(chosen.tick())

    def on_reset(self) -> None:
        super().on_reset()
        self._active = None

    def utility(self) -> Utility:
        return fallback_utility([c.utility() for c in self.children])
