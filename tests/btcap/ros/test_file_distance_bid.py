"""A distance bid declared in an implementation file (``bid: {distance_from: ...}``),
priced by each robot's ROS bridge from the pose on its own topic: of two robots at
different poses, the nearer one wins the auction."""

from __future__ import annotations

from pathlib import Path

import anyio
import pytest
from capfixtures import team, until
from rosservers import Servers

from btcap.bt.registry import default_registry
from btcap.bt.state import State
from btcap.ros.agent import RosAgent, register
from btcap.ros.errors import RosError
from btcap.team.capabilities.capfiles import load_implementation, load_interfaces
from btcap.team.rossettings import RosSettings

pytestmark = pytest.mark.ros

EXAMPLE = Path(__file__).resolve().parents[3] / "examples" / "ros2"

INTERFACES = """\
btcap_interfaces: 1
interfaces:
  - name: Compute
    inputs: {order: int, goal: "list[float]"}
    outputs: {sequence: "list[int]"}
"""

IMPLEMENTATION = """\
btcap_implementation: 1
name: compute-by-distance
interface: Compute
tree: {tree}
cost: 1.0
bid:
  distance_from: {{topic: pose, type: {type}}}
  to: goal
  factor: 2.0
"""


def files(tmp_path: Path, pose_type: str = "geometry_msgs/msg/PoseStamped") -> Path:
    (tmp_path / "interfaces.yaml").write_text(INTERFACES)
    impl = tmp_path / "compute.yaml"
    impl.write_text(IMPLEMENTATION.format(tree=EXAMPLE / "compute_impl.xml", type=pose_type))
    return impl


async def test_the_nearer_robot_wins_by_the_distance_its_file_declares(
    tmp_path: Path, ros_domain: int
) -> None:
    impl_file = files(tmp_path)
    settings = RosSettings(domain_id=ros_domain)
    far = Servers("/husky1", domain_id=ros_domain, pose=(10.0, 0.0))
    near = Servers("/husky2", domain_id=ros_domain, pose=(3.0, 4.0))
    with far, near, anyio.fail_after(40):
        sides = {robot: RosAgent(settings, robot) for robot in ("husky1", "husky2")}
        try:
            impls = {}
            for robot, side in sides.items():
                await side.start()
                registry = register(default_registry())
                ifaces = load_interfaces(tmp_path / "interfaces.yaml", registry)
                (impls[robot],) = side.wrap([load_implementation(impl_file, ifaces, registry)])
            goal = {"order": 3, "goal": [0.0, 0.0]}
            for robot in impls:
                await until(lambda r=robot: impls[r].cost(goal) is not None, f"{robot}'s pose")
            # Its cost + factor x distance: 1 + 2 x 5 beats 1 + 2 x 10 (the tree's own
            # expected cost comes on top of both alike).
            near_cost, far_cost = impls["husky2"].cost(goal), impls["husky1"].cost(goal)
            assert near_cost is not None
            assert far_cost is not None
            assert far_cost - near_cost == pytest.approx(2.0 * (10.0 - 5.0))
            async with team(real_time=True) as t:
                for robot, side in sides.items():
                    side.attach((await t.add(robot, [impls[robot]])).system)
                await t.converged(impls["husky1"].interface.identity)
                node = impls["husky1"].interface.node_type()("compute", inputs=goal)
                assert await t["husky1"].run_mission(node) is State.SUCCEEDED
                assert node.assignments == ["husky2"]
                assert node.outputs["sequence"] == [0, 1, 1, 2, 3]
            assert near.events["fibonacci.succeeded"] == 1
            assert far.events["fibonacci.succeeded"] == 0
        finally:
            for side in sides.values():
                await side.close()


async def test_a_pose_type_that_is_no_message_is_one_line_naming_the_file(
    tmp_path: Path, ros_domain: int
) -> None:
    impl_file = files(tmp_path, pose_type="geometry_msgs/msg/NoSuchPose")
    side = RosAgent(RosSettings(domain_id=ros_domain), "husky1")
    with anyio.fail_after(20):
        await side.start()
        try:
            registry = register(default_registry())
            ifaces = load_interfaces(tmp_path / "interfaces.yaml", registry)
            impl = load_implementation(impl_file, ifaces, registry)
            with pytest.raises(RosError) as err:
                side.wrap([impl])
        finally:
            await side.close()
    line = str(err.value)
    assert "\n" not in line
    assert line.startswith(f"{impl_file}: bid.distance_from: ")
    assert "NoSuchPose" in line
