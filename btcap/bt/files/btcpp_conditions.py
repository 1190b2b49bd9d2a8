"""BehaviorTree.CPP's pre/post-condition attributes (``_failureIf``, ``_onSuccess``…) of
any node, read into a :class:`~btcap.bt.scripting.nodes.ScriptConditions` around it.

``_skipIf`` and ``_while`` return BehaviorTree.CPP's SKIPPED, which btcap does not have;
a file using them is refused with the reason.
"""

from __future__ import annotations

from collections.abc import Callable

from btcap.bt.files.btcpp_nodes import MappingError, script_code
from btcap.bt.files.schema import NodeSpec
from btcap.bt.files.xmlread import XmlElement
from btcap.bt.scripting.nodes import CONDITIONS

__all__ = ["take_conditions", "wrap"]

_SKIPPING = ("_skipIf", "_while")


def take_conditions(
    el: XmlElement, attrs: dict[str, str], fail: Callable[[int, str], None]
) -> dict[str, str]:
    """Pop the condition attributes from ``attrs``: ScriptConditions options by name."""
    out: dict[str, str] = {}
    for key in [k for k in attrs if k in CONDITIONS or k in _SKIPPING]:
        code = attrs.pop(key)
        if key in _SKIPPING:
            fail(
                el.line,
                f"<{el.tag}> attribute {key!r}: it makes the node SKIPPED, a state btcap "
                f"does not have; use a Precondition (its else= gives SUCCESS, FAILURE or "
                f"RUNNING) or _failureIf/_successIf",
            )
            continue
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
