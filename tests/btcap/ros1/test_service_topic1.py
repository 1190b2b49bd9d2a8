"""RosService and the topic nodes over ROS 1, and an agent whose file says ``backend:
ros1`` running its implementation on a real actionlib server (examples/ros1)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import anyio
import msgspec
import pytest
from conftest import Servers
from rosmaster1 import Master
from tools1 import FOUND_S, bridge_on, run, settle

from btcap.bt.composites import Parallel
from btcap.bt.files import load_tree
from btcap.bt.registry import default_registry
from btcap.bt.state import State
from btcap.bt.tree import Tree
from btcap.ros import wire1
from btcap.ros.nodes1 import RosPublish, RosService, RosSubscribe, RosWaitForMessage
from btcap.team.deployment.agentconfig import AgentConfigError, RobotConfig, load_agent_file
from btcap.team.deployment.deploy import open_agent

pytestmark = pytest.mark.ros1

EXAMPLE = Path(__file__).resolve().parents[3] / "examples" / "ros1"


async def test_a_service_call_fills_the_outputs(master: Master, servers: Servers) -> None:
    with anyio.fail_after(30):
        async with bridge_on(master) as bridge:
            node = RosService(
                "flag",
                service_type="std_srvs/SetBool",
                service_name="set_flag",
                bridge=bridge,
                inputs={"data": True},
                server_timeout=FOUND_S,
            )
            assert await run(node) is State.SUCCEEDED, node.error
    assert node.outputs == {"success": True, "message": "flag True"}
    assert servers.events["set_flag.called"] == 1


@pytest.mark.parametrize(
    ("name", "why"),
    [
        ("stall", "service /husky1/stall (std_srvs/Trigger): no response within server_timeout"),
        (
            "nobody",
            "service /husky1/nobody (std_srvs/Trigger): no server within "
            "wait_for_server_timeout 0.5 s",
        ),
    ],
)
async def test_a_slow_or_missing_service_fails_saying_which(
    master: Master, servers: Servers, name: str, why: str
) -> None:
    with anyio.fail_after(30):
        async with bridge_on(master) as bridge:
            node = RosService(
                "call",
                service_type="std_srvs/Trigger",
                service_name=name,
                bridge=bridge,
                server_timeout=0.5,
                wait_for_server_timeout=FOUND_S if name == "stall" else 0.5,
            )
            assert await run(node) is State.FAILED
    assert why in str(node.error)


async def test_a_topic_round_trip_through_a_rospy_node(master: Master, servers: Servers) -> None:
    """Publish on chatter_in at 20 Hz until the servers' echo comes back on chatter_out."""
    with anyio.fail_after(30):
        async with bridge_on(master) as bridge:
            pub = RosPublish(
                "say",
                topic_type="std_msgs/String",
                topic_name="chatter_in",
                rate_hz=20.0,
                bridge=bridge,
                inputs={"data": "hi"},
            )
            wait = RosWaitForMessage(
                "hear", topic_type="std_msgs/String", topic_name="chatter_out", bridge=bridge
            )
            latest = RosSubscribe(
                "last",
                topic_type="std_msgs/String",
                topic_name="chatter_out",
                fields=["data"],
                bridge=bridge,
            )
            Tree(latest).setup()  # subscribed from now on
            both = Parallel("both", children=[pub, wait], success_threshold=1)
            assert await run(both) is State.SUCCEEDED, wait.error
            assert wait.outputs["data"] == "echo: hi"
            assert await run(latest) is State.SUCCEEDED
            assert latest.outputs == {"message": {"data": "echo: hi"}, "data": "echo: hi"}


def husky1(master: Master) -> RobotConfig:
    config = load_agent_file(EXAMPLE / "husky1.yaml")
    assert config.spec.ros is not None
    assert config.spec.ros.backend == "ros1"
    ros = msgspec.structs.replace(config.spec.ros, master_uri=master.uri)
    return dataclasses.replace(config, spec=msgspec.structs.replace(config.spec, ros=ros))


async def test_the_example_agent_runs_its_xml_implementation_over_ros1(
    master: Master, servers: Servers
) -> None:
    registry = default_registry()
    with anyio.fail_after(40):
        async with open_agent(husky1(master), registry) as agent:
            mission = load_tree(EXAMPLE / "mission.yaml", registry)
            assert await agent.run_mission(mission) is State.SUCCEEDED
            assert mission.root.outputs["doubled"] == 8
    assert servers.events["count.succeeded"] == 1


async def test_an_agent_on_an_unreachable_master_is_one_line(master: Master) -> None:
    config = husky1(master)
    master.stop()
    with anyio.fail_after(20), pytest.raises(AgentConfigError) as err:
        async with open_agent(config, default_registry()):
            pass
    line = str(err.value)
    assert "\n" not in line
    assert f"husky1.yaml: ros: ROS 1 master {master.uri} does not answer" in line


async def test_a_distance_cost_reads_the_robots_pose_over_ros1(master: Master) -> None:
    from btcap.ros.capability import distance_cost

    pose = {"header": {"frame_id": "map"}, "pose": {"position": {"x": 3.0, "y": 4.0}}}
    cost = distance_cost(pose_topic="pose", factor=2.0)
    with anyio.fail_after(30):
        async with bridge_on(master) as bridge:
            assert cost({"goal": [0.0, 0.0]}, bridge) is None  # no pose yet: no bid
            say = RosPublish(
                "pose",
                topic_type="geometry_msgs/PoseStamped",
                topic_name="pose",
                rate_hz=20.0,
                bridge=bridge,
                inputs=pose,
            )
            await run(say, lambda s: bridge.latest("geometry_msgs/PoseStamped", "pose") is not None)
            assert cost({"goal": [0.0, 0.0]}, bridge) == 10.0


async def test_a_service_gone_for_a_moment_stays_available_and_one_gone_for_good_does_not(
    master: Master, servers: Servers, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The master forgets ``set_flag`` for 0.4 s (four of the child's 0.1 s checks fail, as
    under load): the robot keeps bidding (no availability change reaches the bridge); then
    for good: it stops, a window later."""
    with anyio.fail_after(30):
        async with bridge_on(master) as bridge:
            seen: list[bool] = []
            dispatch = bridge._dispatch

            def record(frame: object) -> None:
                if isinstance(frame, wire1.Ready):
                    seen.append(frame.ready)
                dispatch(frame)

            monkeypatch.setattr(bridge, "_dispatch", record)
            ready = lambda: bridge.server_ready("service", "std_srvs/SetBool", "set_flag")  # noqa: E731
            await settle(ready)
            seen.clear()
            name, node = "/husky1/set_flag", "/husky1/servers"
            with master.proxy() as proxy:
                _, _, uri = proxy.lookupService(node, name)
                _, _, api = proxy.lookupNode(node, node)
                assert proxy.unregisterService(node, name, uri)[2] == 1
                await anyio.sleep(0.4)
                proxy.registerService(node, name, uri, api)
                await anyio.sleep(0.3)  # a check or more after it came back
                assert seen == []
                assert ready()
                proxy.unregisterService(node, name, uri)
            await settle(lambda: not ready())
            assert seen == [False]


async def test_a_service_killed_mid_call_fails_the_node_saying_why(
    master: Master, servers: Servers
) -> None:
    """As on ROS 2 (tests/btcap/ros/test_action_faults.py): not at server_timeout."""
    with anyio.fail_after(30):
        async with bridge_on(master) as bridge:
            node = RosService(
                "call",
                service_type="std_srvs/Trigger",
                service_name="stall",
                bridge=bridge,
                server_timeout=60.0,
                wait_for_server_timeout=FOUND_S,
            )
            await run(node, lambda s: servers.events["stall.called"] == 1)
            servers.kill()
            assert await run(node) is State.FAILED
    why = str(node.error)
    assert why.startswith("RosService 'call': service /husky1/stall (std_srvs/Trigger): ")
    assert "the call failed: " in why or why.endswith("the server left during the call"), why
