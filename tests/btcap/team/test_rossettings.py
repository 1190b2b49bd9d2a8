"""The ``ros:`` block of agent files: its fields checked as the file is read, one line
naming the field, without ROS installed."""

from __future__ import annotations

from pathlib import Path

import pytest

from btcap.team.deployment.agentconfig import AgentConfigError, load_agent_file
from btcap.team.rossettings import Qos, RosSettings


@pytest.mark.parametrize(
    ("block", "why"),
    [
        ("{namespace: husky1}", "ros.namespace: 'husky1' is no ROS 2 namespace"),
        ("{namespace: /1husky}", "ros.namespace: '/1husky' is no ROS 2 namespace"),
        ("{node_name: my-node}", "ros.node_name: 'my-node' is no ROS 2 node name"),
        # A ROS 1 block's errors name ROS 1 (they said "ROS 2" whatever the backend).
        ("{backend: ros1, namespace: husky1}", "ros.namespace: 'husky1' is no ROS 1 namespace"),
        ("{backend: ros1, node_name: my-node}", "ros.node_name: 'my-node' is no ROS 1 node name"),
        ("{domain_id: 300}", "ros.domain_id: Expected `int` <= 232"),
        (
            "{qos: {reliability: sometimes}}",
            "ros.qos.reliability: Invalid enum value 'sometimes'; expected one of",
        ),
        ("{qos: {depth: 0}}", "ros.qos.depth: Expected `int` >= 1"),
        (
            "{backend: ros1, master_uri: 'localhost:11311'}",
            "ros.master_uri: 'localhost:11311' is no ROS 1 master URI: expected http://HOST:PORT/",
        ),
        ("{master_uri: 'http://localhost/'}", "ros.master_uri: 'http://localhost/' is no ROS 1"),
        ("{master_uri: 'http://h:99999/'}", "ros.master_uri: 'http://h:99999/' is no ROS 1"),
        (
            "{domian_id: 3}",
            "ros: Object contains unknown field `domian_id`; "
            "expected one of backend, master_uri, domain_id",
        ),
    ],
)
def test_a_bad_ros_field_is_one_line_naming_it(tmp_path: Path, block: str, why: str) -> None:
    path = tmp_path / "agent.yaml"
    path.write_text(f"btcap: 1\nrobot: husky1\nros: {block}\n")
    with pytest.raises(AgentConfigError) as err:
        load_agent_file(path)
    line = str(err.value)
    assert "\n" not in line
    assert str(path) in line
    assert why in line


def test_the_namespace_defaults_to_the_robots_name() -> None:
    settings = RosSettings()
    assert settings.namespace_of("husky1") == "/husky1"
    assert RosSettings(namespace="/team/h1").namespace_of("husky1") == "/team/h1"
    assert settings.qos == Qos(reliability="reliable", durability="volatile", depth=10)
    with pytest.raises(ValueError, match=r"from the robot's name 'bad name'"):
        settings.namespace_of("bad name")


def test_a_ros1_robot_whose_name_makes_no_namespace_is_told_so_in_ros1s_terms() -> None:
    with pytest.raises(ValueError, match=r"'/bad name' is no ROS 1 namespace"):
        RosSettings(backend="ros1").namespace_of("bad name")
    with pytest.raises(ValueError, match=r"'/bad name' is no ROS 2 namespace"):
        RosSettings().namespace_of("bad name")
