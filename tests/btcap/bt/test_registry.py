"""Node registry: built-ins, registration rules, plugin entry points, type names."""

from __future__ import annotations

import importlib.metadata
from collections.abc import Callable
from typing import Any

import msgspec
import pytest

import btcap
from btcap import (
    Constant,
    Leaf,
    Node,
    NodeRegistry,
    ReactiveSequence,
    RegistryError,
    State,
    TreeError,
    default_registry,
)
from btcap.bt import composites, decorators, leaves
from btcap.bt.registry import ENTRY_POINT_GROUP


class Battery(Leaf):
    """A plugin-style node."""

    OPTIONS = {"minimum": float}

    def on_tick(self) -> State:
        return State.SUCCEEDED


class Gripper(Leaf):
    def on_tick(self) -> State:
        return State.SUCCEEDED


class FakeEntryPoint:
    """What the registry uses of importlib.metadata.EntryPoint."""

    def __init__(self, name: str, load: Callable[[], Any], value: str = "pkg.mod:attr") -> None:
        self.name = name
        self.value = value
        self._load = load

    def load(self) -> Any:
        return self._load()


@pytest.fixture
def plugins(monkeypatch: pytest.MonkeyPatch) -> list[FakeEntryPoint]:
    """Entry points the registry will see; tests append to this list."""
    eps: list[FakeEntryPoint] = []
    groups: list[str] = []

    def entry_points(*, group: str) -> list[FakeEntryPoint]:
        groups.append(group)
        return eps if group == ENTRY_POINT_GROUP else []

    monkeypatch.setattr(importlib.metadata, "entry_points", entry_points)
    return eps


# -- built-ins ------------------------------------------------------------------------
def test_default_registry_has_every_builtin_that_a_file_can_build() -> None:
    reg = default_registry(plugins=False)
    exported = {
        name
        for module in (composites, decorators, leaves)
        for name in module.__all__
        if isinstance(getattr(module, name), type) and issubclass(getattr(module, name), Node)
    }
    assert exported - set(reg) == {"Action", "Condition", "Decorator", "Remap"}
    assert {
        "ReactiveSequence",
        "ReactiveFallback",
        "Parallel",
        "Retry",
        "Timeout",
        "Constant",
        "Wait",
    } <= set(reg)
    assert reg.get("ReactiveSequence") is ReactiveSequence
    assert reg.name_of(Constant) == "Constant"
    assert "Subtree" not in reg
    assert "Action" not in reg
    assert "Condition" not in reg
    assert len(reg) == len(reg.names()) == len(reg.items())


def test_each_default_registry_is_new() -> None:
    a, b = default_registry(plugins=False), default_registry(plugins=False)
    a.register(Battery)
    assert "Battery" in a
    assert "Battery" not in b


def test_default_registry_reads_the_real_entry_points() -> None:
    # The project declares an (empty) btcap.nodes group: loading it must just work.
    assert "ReactiveSequence" in default_registry()


# -- registering ----------------------------------------------------------------------
def test_register_works_as_decorator_and_under_another_name() -> None:
    reg = NodeRegistry()
    assert reg.register(Battery) is Battery
    reg.register(Battery, "acme.Battery")
    assert reg.get("Battery") is reg.get("acme.Battery") is Battery
    assert reg.name_of(Battery) == "Battery"  # the first name is the one files get


def test_duplicate_names_are_rejected_naming_both_classes() -> None:
    reg = NodeRegistry()
    reg.register(Battery)

    class Other(Leaf):
        def on_tick(self) -> State:
            return State.SUCCEEDED

    with pytest.raises(
        RegistryError, match=r"'Battery' is already registered \(.*Battery\); cannot add .*Other"
    ):
        reg.register(Other, "Battery")


def test_a_user_type_named_like_a_builtin_is_kept_apart() -> None:
    """YAML and Python keep btcap's Wait by its plain name; XML means the user's."""
    reg = default_registry(plugins=False)

    class Wait(Leaf):  # Nav2's Wait: a wait_duration input, nothing like btcap's
        INPUTS = {"wait_duration": float}

        def on_tick(self) -> State:
            return State.SUCCEEDED

    assert reg.register(Wait) is Wait
    assert reg.get("Wait") is leaves.Wait
    assert reg.get("user.Wait") is Wait
    assert reg.name_of(Wait) == "user.Wait"  # so a dumped tree loads back the same
    assert reg.xml_type("Wait") == "user.Wait"
    assert reg.xml_type("Log") is None  # btcap's own: no XML element means it...
    assert reg.xml_type("btcap.Log") == "Log"  # ...unless it says so
    assert reg.xml_type("Battery") is None

    class Wait2(Leaf):
        def on_tick(self) -> State:
            return State.SUCCEEDED

    with pytest.raises(
        RegistryError, match=r"'Wait' is already registered \(.*\.Wait\); cannot add .*Wait2"
    ):
        reg.register(Wait2, "Wait")
    copy = reg.copy()
    copy.register(Battery)
    assert "Battery" in copy
    assert "Battery" not in reg


@pytest.mark.parametrize(
    ("cls", "name", "match"),
    [
        (Battery, "Subtree", "reserved"),
        (Battery, "not a name", "identifier"),
        (Battery, "", "identifier"),
        (int, None, "expected a Node subclass"),
    ],
)
def test_register_rejects_bad_entries(cls: Any, name: str | None, match: str) -> None:
    with pytest.raises(RegistryError, match=match):
        NodeRegistry().register(cls, name)


def test_unknown_type_lists_close_matches_and_is_a_tree_error() -> None:
    reg = default_registry(plugins=False)
    with pytest.raises(TreeError, match=r"unknown node type 'Sequnce' \(did you mean Sequence"):
        reg.get("Sequnce")
    with pytest.raises(RegistryError, match=r"'Zzz'; 'btcap tree nodes' lists the known types$"):
        reg.get("Zzz")
    with pytest.raises(RegistryError, match="subtrees"):
        reg.get("Subtree")


def test_name_of_an_unregistered_class_says_to_register_it() -> None:
    with pytest.raises(RegistryError, match="Gripper is not registered"):
        default_registry(plugins=False).name_of(Gripper)


# -- plugins --------------------------------------------------------------------------
def test_plugin_class_and_plugin_callable_are_registered(plugins: list[FakeEntryPoint]) -> None:
    plugins.append(FakeEntryPoint("battery", lambda: Battery))
    plugins.append(FakeEntryPoint("more", lambda: lambda: [Gripper]))
    reg = default_registry()
    assert reg.get("Battery") is Battery
    assert reg.get("Gripper") is Gripper
    assert "ReactiveSequence" in reg


def test_no_plugins_skips_entry_points(plugins: list[FakeEntryPoint]) -> None:
    plugins.append(FakeEntryPoint("broken", lambda: 1 / 0))
    assert "Battery" not in default_registry(plugins=False)


def _raise_import() -> Any:
    raise ImportError("No module named 'acme_nodes'")


def _not_a_node() -> Any:
    return int


def _returns_junk() -> Any:
    return lambda: [Battery, "Gripper"]


def _call_fails() -> Any:
    def make() -> list[type[Node]]:
        raise RuntimeError("no hardware")

    return make


@pytest.mark.parametrize(
    ("load", "match"),
    [
        (_raise_import, r"failed to load: ImportError: No module named 'acme_nodes'"),
        (_not_a_node, "int is not a Node subclass"),
        (lambda: 42, "expected a Node subclass or a callable"),
        (_returns_junk, "returned 'Gripper'; expected only Node subclasses"),
        (_call_fails, "calling it failed: RuntimeError: no hardware"),
        (lambda: ReactiveSequence, "'ReactiveSequence' is already registered"),
    ],
)
def test_broken_plugin_errors_name_the_entry_point(
    plugins: list[FakeEntryPoint], load: Callable[[], Any], match: str
) -> None:
    plugins.append(FakeEntryPoint("acme", load, value="acme_nodes:nodes"))
    with pytest.raises(RegistryError, match=match) as info:
        default_registry()
    assert "node plugin 'acme' (acme_nodes:nodes) in entry-point group 'btcap.nodes'" in str(
        info.value
    )


# -- type names -----------------------------------------------------------------------
@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("int", int),
        ("float", float),
        ("str", str),
        ("bool", bool),
        ("Any", Any),
        ("None", type(None)),
        ("list[float]", list[float]),
        ("tuple[float, float]", tuple[float, float]),
        ("tuple[int, ...]", tuple[int, ...]),
        ("dict[str, int]", dict[str, int]),
        ("set[str]", set[str]),
        ("int | None", int | None),
        ("dict[str, list[float | None]] | None", dict[str, list[float | None]] | None),
        ("  list[ int ]  ", list[int]),
    ],
)
def test_type_names_parse_and_format_back(text: str, expected: Any) -> None:
    reg = NodeRegistry()
    tp = reg.parse_type(text)
    assert tp == expected
    assert reg.parse_type(reg.format_type(tp)) == expected
    if text == text.strip() and " ]" not in text:
        assert reg.format_type(tp) == text


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("lst[int]", r"unknown name 'lst' \(did you mean list"),
        ("list[int", "unexpected end, expected ']'"),
        ("list[int, str]", r"takes 1 type argument\(s\), got 2"),
        ("int]", "unexpected ']'"),
        ("", "empty type name"),
        ("int |", "unexpected end"),
        ("tuple[...]", "only fits as tuple"),
        ("list[...]", "only fits as tuple"),
        ("float[int]", "takes no type arguments"),
        ("__import__('os')", "unexpected character '\\('"),
        ("os.system", "unknown name 'os.system'"),
    ],
)
def test_bad_type_names_are_rejected_without_eval(text: str, match: str) -> None:
    with pytest.raises(RegistryError, match=match) as info:
        NodeRegistry().parse_type(text)
    assert f"type {text!r}" in str(info.value)


class Pose(msgspec.Struct):
    x: float
    y: float


def test_registered_types_can_be_named_in_files() -> None:
    reg = NodeRegistry(types={"geo.Pose": Pose})
    assert reg.parse_type("list[geo.Pose] | None") == list[Pose] | None
    assert reg.format_type(dict[str, Pose]) == "dict[str, geo.Pose]"
    reg.register_type("geo.Pose", Pose)  # the same again is fine
    with pytest.raises(RegistryError, match="already taken"):
        reg.register_type("geo.Pose", int)
    with pytest.raises(RegistryError, match="no name in files"):
        NodeRegistry().format_type(Pose)


def test_fallback_with_memory_is_gone_and_its_name_says_use_fallback() -> None:
    assert not hasattr(btcap, "FallbackWithMemory")
    reg = default_registry(plugins=False)
    assert "FallbackWithMemory" not in reg
    with pytest.raises(
        RegistryError, match=r"'FallbackWithMemory': it was removed in btcap 0\.2; use Fallback,"
    ):
        reg.get("FallbackWithMemory")
