"""BehaviorTree.CPP's pre/post-condition attributes (``_failureIf``, ``_onSuccess``…) of
any node, read into a :class:`~btcap.bt.scripting.nodes.ScriptConditions` around it.

``_skipIf`` and ``_while`` give BehaviorTree.CPP's SKIPPED (:attr:`State.SKIPPED
<btcap.bt.state.State.SKIPPED>`): the parent goes on as if the node were absent.
"""

from __future__ import annotations

from collections.abc import Callable

from btcap.bt.files.btcpp_nodes import MappingError, script_code
from btcap.bt.files.schema import NodeSpec
from btcap.bt.files.xmlread import XmlElement
from btcap.bt.scripting.nodes import CONDITIONS

__all__ = ["take_conditions", "wrap"]


def take_conditions(
    el: XmlElement, attrs: dict[str, str], fail: Callable[[int, str], None]
) -> dict[str, str]:
    """Pop the condition attributes from ``attrs``: ScriptConditions options by name."""
    out: dict[str, str] = {}
    for key in [k for k in attrs if k in CONDITIONS]:
        code = attrs.pop(key)
        try:
            out[CONDITIONS[key]] = script_code(code)
        except MappingError as exc:
            fail(el.line, f"<{el.tag}> attribute {key!r}: {exc}")
    return out


def wrap(inner: NodeSpec | None, name: str, conditions: dict[str, str]) -> NodeSpec | None:
    """The node inside the decorator that runs its conditions (both have its name)."""
    if inner is None:
        return None
    return NodeSpec(type="ScriptConditions", name=name, options=conditions, children=[inner])
