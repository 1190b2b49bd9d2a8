"""What BehaviorTree.CPP 4.8 itself checks when it loads a file, checked the same way.

- ``<TreeNodesModel>`` may declare BehaviorTree.CPP's own nodes, as its ``log_test.xml``
  and files saved by Groot do (``<Action ID="Sleep"><input_port name="msec"/>``). Such an
  entry uses BehaviorTree.CPP's port names, not btcap's (``Sleep msec`` is btcap's
  ``Wait seconds``): it is checked against the ports of BehaviorTree.CPP's node, and
  refused only where it contradicts them (a port the node does not have, an input
  declared as an output, another kind of node).
- A ``ReactiveSequence`` with more than one ``<AsyncSequence>`` child is refused when
  the file loads, with BehaviorTree.CPP's reason (its ``VerifyXML``). Its check looks
  each child's element name up among the registered node types, so a generic
  ``<Action ID="X"/>`` element directly below a ``ReactiveSequence`` is refused too
  ("Unknown node type: Action"). ``ReactiveFallback`` is not checked, and neither is a
  second running child at tick time (BehaviorTree.CPP throws there only after
  ``ReactiveSequence::EnableException(true)``, off by default).
"""

from __future__ import annotations

from collections.abc import Callable

from btcap.bt.files.btcpp_nodes import STANDARD
from btcap.bt.files.xmlread import XmlElement

__all__ = ["BUILTIN_PORTS", "check_builtin_model", "check_reactive"]

#: Fails a problem: (line, message, file).
Fail = Callable[[int, str, str], None]

_GENERIC = ("Action", "Condition", "Control", "Decorator")

#: The kind of node each mapped built-in is in BehaviorTree.CPP (its model's tag).
_KINDS: dict[str, str] = {
    **dict.fromkeys(
        (
            *("Sequence", "AsyncSequence", "SequenceWithMemory", "Fallback"),
            *("AsyncFallback", "ReactiveSequence", "ReactiveFallback", "Parallel"),
            *("ParallelAll", "IfThenElse", "WhileDoElse"),
        ),
        "Control",
    ),
    **dict.fromkeys(
        (
            *("Inverter", "ForceSuccess", "ForceFailure", "KeepRunningUntilFailure"),
            *("RetryUntilSuccessful", "Repeat", "Timeout", "Delay", "RunOnce"),
            "Precondition",
        ),
        "Decorator",
    ),
    **dict.fromkeys(
        ("AlwaysSuccess", "AlwaysFailure", "Sleep", "Script", "SetBlackboard"), "Action"
    ),
    "ScriptCondition": "Condition",
}

#: BehaviorTree.CPP 4.8's ports of each mapped built-in: name -> input, output or inout.
BUILTIN_PORTS: dict[str, dict[str, str]] = {
    **{name: dict.fromkeys(std.attrs, "input") for name, std in STANDARD.items()},
    "SetBlackboard": {"value": "input", "output_key": "inout"},
}

_TAGS = {"input_port": "input", "output_port": "output", "inout_port": "inout"}


def _an(word: str) -> str:
    return f"an {word}" if word[0].upper() in "AEIOU" else f"a {word}"


def check_builtin_model(model: XmlElement, fail: Fail, where: str) -> None:
    """A ``<TreeNodesModel>`` entry of a BehaviorTree.CPP built-in must agree with it."""
    kind = model.attrs["ID"]
    ports = BUILTIN_PORTS[kind]
    where = model.where or where
    said = f"<TreeNodesModel> {model.tag} {kind!r}"
    if model.tag != _KINDS[kind]:
        fail(
            model.line,
            f"{said}: BehaviorTree.CPP's {kind} is {_an(_KINDS[kind])}, not {_an(model.tag)}",
            where,
        )
    have = ", ".join(f"{name} ({way})" for name, way in ports.items()) or "none"
    for port in model.children:
        name = port.attrs.get("name", "")
        way = _TAGS.get(port.tag)
        if way is None:
            continue  # a description or metadata element
        if name not in ports:
            fail(
                port.line,
                f"{said} {port.tag} {name!r}: BehaviorTree.CPP's {kind} has no such port "
                f"(its ports: {have})",
                where,
            )
        elif way != ports[name] and ports[name] != "inout":
            fail(
                port.line,
                f"{said} {port.tag} {name!r}: BehaviorTree.CPP's {kind} port {name!r} is "
                f"{_an(ports[name])} port",
                where,
            )


def check_reactive(el: XmlElement, kind: str, fail: Callable[[int, str], None]) -> None:
    """Refuse a ReactiveSequence's children as BehaviorTree.CPP 4.8's VerifyXML does."""
    if kind != "ReactiveSequence":
        return
    asyncs = []
    for child in el.children:
        if child.tag in _GENERIC:
            ident = child.attrs.get("ID", "")
            fail(
                child.line,
                f"<{child.tag} ID={ident!r}> directly below a ReactiveSequence: "
                f'BehaviorTree.CPP 4.8 refuses it ("Unknown node type: {child.tag}", its '
                f"check of a ReactiveSequence's children reads the element name); write "
                f"<{ident or 'TYPE'}/>",
            )
        elif child.tag == "AsyncSequence":
            asyncs.append(str(child.line))
    if len(asyncs) > 1:
        fail(
            el.line,
            f'<{el.tag}>: BehaviorTree.CPP 4.8 refuses it: "A ReactiveSequence cannot have '
            f'more than one async child." (<AsyncSequence> children at lines '
            f"{', '.join(asyncs)})",
        )
