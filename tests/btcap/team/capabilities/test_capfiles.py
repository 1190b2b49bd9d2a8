"""Interfaces and implementations declared in files."""

from __future__ import annotations

from pathlib import Path

import anyio
import pytest

from btcap import ReactiveSequence, State
from btcap.team.capabilities.capfiles import (
    CapabilityFileError,
    load_implementation,
    load_interfaces,
)
from btcap.team.runtime.agent import Agent

EXAMPLES = Path(__file__).resolve().parents[4] / "examples" / "capabilities"


def test_interfaces_load_with_typed_ports() -> None:
    (greet,) = load_interfaces(EXAMPLES / "interfaces.yaml")
    assert greet.name == "Greet"
    assert greet.inputs["who"].type is str
    assert greet.identity == "Greet(who:str)->(said:str)"


async def test_an_implementation_from_files_runs_through_its_bridges() -> None:
    interfaces = load_interfaces(EXAMPLES / "interfaces.yaml")
    impl = load_implementation(EXAMPLES / "greet.yaml", interfaces)
    assert impl.cost({"who": "x"}) == 1.0
    with anyio.fail_after(10):
        async with Agent("solo", implementations=[impl]) as agent:
            node = interfaces[0].node_type()("greet", inputs={"who": "world"})
            state = await agent.run_mission(ReactiveSequence("m", children=[node]), rate_hz=100)
    assert state is State.SUCCEEDED
    assert node.outputs == {"said": "world"}
    assert node.assignments == ["solo"]


def test_an_implementations_tree_file_is_read_and_parsed_once(tmp_path: Path) -> None:
    """Every run builds a fresh tree, but not from the file: reading and parsing it (most
    of a build's cost, on the robot's event loop at an award) happens once, at load."""
    for name in ("greet.yaml", "greet_impl.yaml"):
        (tmp_path / name).write_bytes((EXAMPLES / name).read_bytes())
    interfaces = load_interfaces(EXAMPLES / "interfaces.yaml")
    impl = load_implementation(tmp_path / "greet.yaml", interfaces)
    first = impl.instantiate()
    (tmp_path / "greet_impl.yaml").write_text("not: [a, tree\n")  # read again: refused
    runs = [impl.instantiate() for _ in range(3)]
    roots = {id(r.tree.root) for r in (first, *runs)}
    assert len(roots) == 4  # each run its own nodes
    assert [n.path for n in runs[-1].tree.nodes()] == [n.path for n in first.tree.nodes()]


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        ("btcap_interfaces: 2\ninterfaces: []\n", "version 2"),
        ("btcap_interfaces: 1\ninterfaces: [{name: X, inputs: {a: nosuchtype}}]\n", "inputs.a"),
        ("btcap_interfaces: 1\ninterfaces: [{name: X, options: {k: 1}}]\n", "no options"),
        ("btcap_interfaces: 1\ninterfaces: [{name: X}, {name: X}]\n", "unique"),
        ("btcap_interfaces: 1\ninterfaces: [{name: X, colour: red}]\n", "colour"),
        ("btcap_interfaces: 1\ninterfaces: [\n", "not valid"),
    ],
)
def test_bad_interface_files_name_the_file_and_field(
    tmp_path: Path, text: str, needle: str
) -> None:
    path = tmp_path / "ifs.yaml"
    path.write_text(text)
    with pytest.raises(CapabilityFileError) as err:
        load_interfaces(path)
    assert str(path) in str(err.value)
    assert needle in str(err.value)


@pytest.mark.parametrize(
    ("body", "needle"),
    [
        ("interface: Nope\ntree: t.yaml\n", "interface: 'Nope'"),
        ("interface: Greet\ntree: missing.yaml\n", "tree:"),
        ("interface: Greet\ntree: t.yaml\nbid: not_a_ref\n", "bid:"),
        ("interface: Greet\ntree: t.yaml\nbid: 'nosuchmodule:fn'\n", "nosuchmodule"),
    ],
)
def test_bad_implementation_files_name_the_file_and_field(
    tmp_path: Path, body: str, needle: str
) -> None:
    (tmp_path / "t.yaml").write_text((EXAMPLES / "greet_impl.yaml").read_text())
    path = tmp_path / "impl.yaml"
    path.write_text(f"btcap_implementation: 1\nname: n\n{body}")
    interfaces = load_interfaces(EXAMPLES / "interfaces.yaml")
    with pytest.raises(CapabilityFileError) as err:
        load_implementation(path, interfaces)
    assert str(path) in str(err.value)
    assert needle in str(err.value)
