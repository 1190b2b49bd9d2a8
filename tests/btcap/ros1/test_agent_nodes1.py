"""An agent whose ``ros:`` block says ``backend: ros1`` registers the ROS 1 node types
under the usual names, through the same :func:`btcap.ros.agent.register` as ROS 2's."""

from __future__ import annotations

import pytest

from btcap.bt.registry import default_registry
from btcap.ros import agent
from btcap.ros.agent import NODE_TYPES, RosAgent
from btcap.ros.nodes1 import NODE_TYPES1
from btcap.team.rossettings import RosSettings

pytestmark = pytest.mark.ros1


def test_a_ros1_agent_registers_the_ros1_node_types_by_the_usual_names() -> None:
    registry = default_registry(plugins=False)
    RosAgent(RosSettings(backend="ros1"), robot="husky1").register(registry)
    assert [registry.get(cls.__name__) for cls in NODE_TYPES1] == list(NODE_TYPES1)
    assert [cls.__name__ for cls in NODE_TYPES1] == [cls.__name__ for cls in NODE_TYPES]


def test_a_name_the_registry_holds_already_is_kept() -> None:
    registry = default_registry(plugins=False)
    agent.register(registry)  # ROS 2's first: ROS 1's do not replace them
    agent.register(registry, NODE_TYPES1)
    assert [registry.get(cls.__name__) for cls in NODE_TYPES] == list(NODE_TYPES)
