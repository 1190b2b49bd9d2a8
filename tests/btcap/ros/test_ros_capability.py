"""A capability whose implementation calls a ROS action, auctioned between two robots in
their own namespaces: the nearer one (by the pose on its topic) wins, and a robot whose
server is gone does not bid."""

from __future__ import annotations

from collections.abc import Iterator

import anyio
import pytest
from capfixtures import team, until
from rosservers import Servers
from rostools import FOUND_S

from btcap.bt.composites import Sequence
from btcap.bt.ports import Port
from btcap.bt.state import State
from btcap.bt.tree import Tree
from btcap.ros.action import RosAction
from btcap.ros.capability import Server, distance_cost, ros_implementation, servers_of
from btcap.ros.client import RosBridge
from btcap.team.capabilities.capability import CapabilityInterface
from btcap.team.rossettings import RosSettings

pytestmark = pytest.mark.ros

FIB = "test_msgs/action/Fibonacci"
COMPUTE = CapabilityInterface(
    "Compute",
    inputs={"order": int, "goal": Port(list[float])},
    outputs={"sequence": list[int]},
    description="a Fibonacci sequence, computed by the robot's ROS action server",
)


def build() -> Tree:
    ib, ob = COMPUTE.bridge_types()
    i, act, o = (
        ib(name="in"),
        RosAction("fib", action_type=FIB, action_name="fibonacci", server_timeout=FOUND_S),
        ob(name="out"),
    )
    tree = Tree(Sequence("compute", children=[i, act, o]))
    tree.wire(i, "order", act, "order")
    tree.wire(act, "sequence", o, "sequence")
    return tree


@pytest.fixture
def far(ros_domain: int) -> Iterator[Servers]:
    with Servers("/husky1", domain_id=ros_domain, pose=(10.0, 0.0)) as s:
        yield s


async def test_the_nearer_robot_wins_until_its_server_goes_then_the_other(
    far: Servers, ros_domain: int
) -> None:
    near = Servers("/husky2", domain_id=ros_domain, pose=(1.0, 0.0)).__enter__()
    settings = RosSettings(domain_id=ros_domain)
    with anyio.fail_after(30):
        async with (
            RosBridge(settings, robot="husky1") as b1,
            RosBridge(settings, robot="husky2") as b2,
        ):
            impls = {
                robot: ros_implementation(
                    f"compute-{robot}", COMPUTE, build, bridge, cost=distance_cost(factor=1.0)
                )
                for robot, bridge in (("husky1", b1), ("husky2", b2))
            }
            assert servers_of(build()) == [Server("action", FIB, "fibonacci")]
            async with team(real_time=True) as t:
                for robot, bridge in (("husky1", b1), ("husky2", b2)):
                    agent = await t.add(robot, [impls[robot]])
                    bridge.provide(agent.system)
                await t.converged(COMPUTE.identity)
                await until(
                    lambda: impls["husky2"].cost({"order": 3, "goal": [0.0, 0.0]}) is not None,
                    "husky2's pose and server",
                )
                await until(
                    lambda: impls["husky1"].cost({"order": 3, "goal": [0.0, 0.0]}) is not None,
                    "husky1's pose and server",
                )
                assert impls["husky2"].cost({"order": 3, "goal": [0.0, 0.0]}) < impls[
                    "husky1"
                ].cost({"order": 3, "goal": [0.0, 0.0]})

                first = COMPUTE.node_type()("compute", inputs={"order": 3, "goal": [0.0, 0.0]})
                assert await t["husky1"].run_mission(first) is State.SUCCEEDED
                assert first.assignments == ["husky2"]
                assert first.outputs["sequence"] == [0, 1, 1, 2, 3]
                assert near.events["fibonacci.succeeded"] == 1

                near.__exit__(None, None, None)  # husky2's servers are gone
                await until(
                    lambda: impls["husky2"].cost({"order": 3, "goal": [0.0, 0.0]}) is None,
                    "husky2 to see its server gone",
                )
                second = COMPUTE.node_type()("compute", inputs={"order": 4, "goal": [0.0, 0.0]})
                assert await t["husky1"].run_mission(second) is State.SUCCEEDED
                assert second.assignments == ["husky1"]
                assert far.events["fibonacci.succeeded"] == 1
