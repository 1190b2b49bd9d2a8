"""A distance bid declared in an implementation file: its fields checked at load, one line
each naming the file and the field; unpriced (no ROS bridge) the robot does not bid, and an
agent file without a ``ros:`` block that uses one is refused in one line. Priced with real
ROS 2 in tests/btcap/ros/test_file_distance_bid.py."""

from __future__ import annotations

from pathlib import Path

import anyio
import pytest

from btcap.bt.registry import default_registry
from btcap.team.capabilities.capfiles import (
    CapabilityFileError,
    DistanceBid,
    FileBid,
    load_implementation,
    load_interfaces,
)
from btcap.team.deployment.agentconfig import AgentConfigError, load_agent_file
from btcap.team.deployment.deploy import open_agent

EXAMPLES = Path(__file__).resolve().parents[4] / "examples" / "capabilities"

INTERFACES = """\
btcap_interfaces: 1
interfaces:
  - {name: Go, inputs: {goal: "list[float]"}, outputs: {said: str}}
"""
TREE = """\
btcap: 1
root: {type: Sequence, name: go, children: [{type: GoInputs, name: in}]}
"""
IMPL = """\
btcap_implementation: 1
name: go-near
interface: Go
tree: tree.yaml
cost: 1.5
bid:
"""


def write(tmp_path: Path, bid: str) -> Path:
    (tmp_path / "interfaces.yaml").write_text(INTERFACES)
    (tmp_path / "tree.yaml").write_text(TREE)
    impl = tmp_path / "go.yaml"
    impl.write_text(IMPL + bid)
    return impl


def load(tmp_path: Path, bid: str) -> FileBid:
    registry = default_registry(plugins=False)
    impl = load_implementation(
        write(tmp_path, bid), load_interfaces(tmp_path / "interfaces.yaml", registry), registry
    )
    assert isinstance(impl.bid, FileBid)
    return impl.bid


def test_a_declared_distance_bid_is_read_with_its_defaults(tmp_path: Path) -> None:
    bid = load(tmp_path, "  distance_from: {}\n  to: goal\n")
    assert bid.distance == DistanceBid(
        "pose", "geometry_msgs/msg/PoseStamped", "goal", 1.0, None, str(tmp_path / "go.yaml")
    )
    assert bid.cost == 1.5
    # Nobody priced it (no ROS bridge wrapped the implementation): the robot does not bid.
    assert bid({"goal": [1.0, 2.0]}) is None
    assert bid.without_distance()({"goal": [1.0, 2.0]}) == 1.5


@pytest.mark.parametrize(
    ("bid", "needle"),
    [
        (
            "  distance_from: {}\n  to: gaol\n",
            "bid.to: 'gaol' is not an input of Go (inputs: goal)",
        ),
        ("  distance_from: {}\n  to: goal\n  factor: -1\n", "bid.factor: -1.0; expected a number"),
        ("  distance_from: {topic: ''}\n  to: goal\n", "bid.distance_from.topic: expected"),
        ("  distance_from: {type: Pose}\n  to: goal\n", "bid.distance_from.type: 'Pose'"),
        ("  distance_from: {max_age_s: 0}\n  to: goal\n", "bid.distance_from.max_age_s: 0"),
        ("  distance_from: {topc: pose}\n  to: goal\n", "topc"),
        ("  to: goal\n", "distance_from"),
        ("  distance_from: {}\n  to: goal\n  function: nosuch:fn\n", "bid: "),
    ],
)
def test_a_bad_field_is_one_line_naming_the_file_and_field(
    tmp_path: Path, bid: str, needle: str
) -> None:
    with pytest.raises(CapabilityFileError) as err:
        load(tmp_path, bid)
    line = str(err.value)
    assert "\n" not in line
    assert line.startswith(str(tmp_path / "go.yaml"))
    assert needle in line


async def test_an_agent_file_without_a_ros_block_is_refused_in_one_line(tmp_path: Path) -> None:
    write(tmp_path, "  distance_from: {}\n  to: goal\n")
    agent = tmp_path / "agent.yaml"
    agent.write_text(
        "btcap: 1\nrobot: r1\n"
        "capabilities: {interfaces: [interfaces.yaml], implementations: [go.yaml]}\n"
    )
    with anyio.fail_after(20), pytest.raises(AgentConfigError) as err:
        async with open_agent(load_agent_file(agent), default_registry()):
            pass
    line = str(err.value)
    assert "\n" not in line
    assert line.startswith(f"{agent}: capabilities.implementations: {tmp_path / 'go.yaml'}: ")
    assert "bid.distance_from reads the robot's pose over ROS 2" in line
    assert "needs a ros: block" in line
