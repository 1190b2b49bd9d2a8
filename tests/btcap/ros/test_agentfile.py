"""Agents configured by files with a ``ros:`` block (examples/ros2): the implementation in
BehaviorTree.ROS2-style XML runs on the robot's server; two robots cannot claim one
namespace."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import anyio
import msgspec
import pytest
from rosservers import Servers

from btcap.bt.files import load_tree
from btcap.bt.registry import default_registry
from btcap.bt.state import State
from btcap.ros import client
from btcap.team.deployment.agentconfig import AgentConfigError, RobotConfig, load_agent_file
from btcap.team.deployment.deploy import open_agent

pytestmark = pytest.mark.ros

EXAMPLE = Path(__file__).resolve().parents[3] / "examples" / "ros2"


def husky1(domain: int, robot: str = "husky1") -> RobotConfig:
    """examples/ros2/husky1.yaml on the test's domain (and as ``robot``, same namespace)."""
    config = load_agent_file(EXAMPLE / "husky1.yaml")
    assert config.spec.ros is not None
    ros = msgspec.structs.replace(config.spec.ros, domain_id=domain)
    spec = msgspec.structs.replace(config.spec, ros=ros, robot=robot)
    return dataclasses.replace(config, spec=spec)


async def test_the_example_agent_runs_its_xml_implementation_on_its_server(
    servers: Servers, ros_domain: int
) -> None:
    registry = default_registry()
    with anyio.fail_after(20):
        async with open_agent(husky1(ros_domain), registry) as agent:
            mission = load_tree(EXAMPLE / "mission.yaml", registry)
            assert await agent.run_mission(mission) is State.SUCCEEDED
            assert mission.root.outputs["sequence"] == [0, 1, 1, 2, 3, 5, 8, 13]
    assert servers.events["fibonacci.succeeded"] == 1


async def test_two_agents_claiming_one_namespace_the_second_is_refused_in_one_line(
    ros_domain: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    registry = default_registry()
    with anyio.fail_after(30):
        async with open_agent(husky1(ros_domain), registry) as first:
            # Discovery can take seconds on a loaded machine: the second watches longer
            # (it stops as soon as it sees the first), so the outcome does not hang on load.
            monkeypatch.setattr(client, "CLAIM_WAIT_S", 15.0)
            with pytest.raises(AgentConfigError) as err:
                async with open_agent(husky1(ros_domain, robot="impostor"), default_registry()):
                    pass
            # The first robot is not harmed by a twin that was refused: its watch waits
            # (2.5 s, its claim check's 1.5 s + 1 s) for a twin that stays.
            bridge = client.RosBridge.of(first.system)
            assert bridge is not None
            await anyio.sleep(3.0)
            assert bridge.conflict is None
    line = str(err.value)
    assert "\n" not in line
    assert "husky1.yaml: ros: namespace '/husky1' is already claimed by another btcap node" in line


async def test_a_twin_discovered_after_start_fails_the_robots_ros_nodes_saying_why(
    ros_domain: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    from rostools import tick_until, tree_of, wait_for

    from btcap.ros import RosAction, RosBridge, RosSettings

    settings = RosSettings(domain_id=ros_domain)
    with anyio.fail_after(30):
        async with RosBridge(settings, robot="husky1"):
            monkeypatch.setattr(client, "CLAIM_WAIT_S", 0.0)  # as if discovery were slow
            async with RosBridge(settings, robot="husky1") as twin:
                await wait_for(lambda: twin.conflict is not None)
                node = RosAction(
                    "act", action_type="test_msgs/action/Fibonacci", action_name="x", bridge=twin
                )
                assert await tick_until(tree_of(node)) is State.ERROR
    assert "namespace '/husky1' is already claimed by another btcap node" in str(node.error)
