"""The ROS tests' ground: rclpy runs, inside a namespace with only loopback, on a domain
of the test's own."""

from __future__ import annotations

import os

import pytest
import rosnet

pytestmark = pytest.mark.ros


def test_the_namespace_has_only_loopback_and_each_test_its_own_domain(ros_domain: int) -> None:
    assert rosnet.private() is None
    assert rosnet.interfaces() == ["lo"]
    assert os.environ["ROS_DOMAIN_ID"] == str(ros_domain)
    assert 1 <= ros_domain <= 101


def test_a_second_test_gets_another_domain(ros_domain: int) -> None:
    first = next(rosnet.domain_ids())
    assert ros_domain != 0
    assert isinstance(first, int)


def test_rclpy_makes_a_node_on_the_tests_domain(ros_domain: int) -> None:
    from btcap.ros.loader import load

    rclpy = load()
    from rclpy.context import Context

    context = Context()
    rclpy.init(context=context, domain_id=ros_domain)
    try:
        node = rclpy.create_node("fixture", namespace="/husky1", context=context)
        assert node.get_namespace() == "/husky1"
        assert context.get_domain_id() == ros_domain
        node.destroy_node()
    finally:
        rclpy.shutdown(context=context)
