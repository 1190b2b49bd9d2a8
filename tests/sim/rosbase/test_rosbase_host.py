"""Which robots' ROS servers the simulator behind ROS starts without (sim/rosbase/host.py):
a robot that joins later is out of the ROS graph until it joins, as a real robot that is
not there yet. Plain suite: building a host imports neither rclpy nor rospy (the servers
themselves are tested in tests/sim/ros2 and tests/sim/ros1)."""

from __future__ import annotations

import pytest

from btcap.actors import Clock
from btcap.sim.ros1.host import Ros1Host
from btcap.sim.ros2.host import Ros2Host
from btcap.sim.running.hosts import registry
from tests.sim.rosbase.rosworld import world


@pytest.mark.parametrize("host_type", [Ros2Host, Ros1Host])
@pytest.mark.parametrize(
    ("name", "absent"), [("huskies-bebop-joins", {"bebop1"}), ("full-team", set())]
)
def test_a_late_joiner_starts_out_of_the_ros_graph(
    host_type: type[Ros2Host | Ros1Host], name: str, absent: set[str]
) -> None:
    s, grid, manager = world(name)
    host = host_type(s, Clock(s.speedup), registry(), grid, manager=manager)
    assert host.withdrawn == absent
