"""``btcap tree validate|run`` on tree files with ROS node types: with ``--ros`` they
load and run against real ROS 2 servers; without, one line per node type saying it needs
ROS 2 and how to get it (not "unknown node type")."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest
from rosservers import Servers

from btcap.cli import main
from btcap.cli.rostree import ROS_TYPES
from btcap.ros.agent import NODE_TYPES

FIB_XML = """<root BTCPP_format="4">
  <BehaviorTree ID="main">
    <Sequence>
      <RosAction name="fib" action_type="test_msgs/action/Fibonacci" action_name="{which}"
                 server_timeout="8.0" order="5" sequence="{sequence}"/>
      <RosService name="call" service_type="std_srvs/srv/SetBool" service_name="set_bool"
                  server_timeout="8.0" data="true"/>
    </Sequence>
  </BehaviorTree>
</root>
"""


@pytest.fixture
def fib_xml(tmp_path: Path) -> Path:
    path = tmp_path / "fib.xml"
    path.write_text(FIB_XML)
    return path


def test_the_cli_knows_the_ros_node_types_by_name() -> None:
    assert tuple(cls.__name__ for cls in NODE_TYPES) == ROS_TYPES


def test_without_ros_each_ros_node_type_is_one_line_saying_so(
    fib_xml: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["tree", "validate", str(fib_xml)]) == 1
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 2, lines
    assert "unknown node type" not in "".join(lines)
    assert lines[0].startswith(
        f"{fib_xml}: line 4: <RosAction>: node type 'RosAction' needs ROS 2:"
    )
    assert lines[1].startswith(f"{fib_xml}: line 6: <RosService>: node type 'RosService' needs")
    if importlib.util.find_spec("rclpy") is None:
        assert "install it with `make ros`" in lines[0]
    else:
        assert "add --ros" in lines[0]


@pytest.mark.skipif(importlib.util.find_spec("rclpy") is not None, reason="ROS 2 is installed here")
def test_ros_asked_for_but_not_installed_is_one_line(
    fib_xml: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["tree", "run", "--ros", str(fib_xml)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert err[0].startswith("btcap: error: --ros: ROS 2 (rclpy")
    assert "install it with `make ros`" in err[0]


@pytest.mark.ros
def test_with_ros_the_file_validates_and_runs_on_the_robot_servers(
    servers: Servers, ros_domain: int, fib_xml: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["tree", "validate", "--ros", str(fib_xml)]) == 0
    assert capsys.readouterr().out.strip() == f"{fib_xml}: ok"
    ros = ["--ros-namespace", "/husky1", "--ros-domain", str(ros_domain)]
    code = main(["tree", "run", *ros, "--set", "which=fibonacci", "--timeout", "30", str(fib_xml)])
    out = capsys.readouterr()
    assert code == 0, out
    assert out.out.strip().splitlines()[-1].startswith("succeeded after")
    assert servers.events["fibonacci.succeeded"] == 1
    assert servers.events["set_bool"] == 1
    assert main(["tree", "run", "--ros", "--fast", str(fib_xml)]) == 2
    assert "--fast with --ros" in capsys.readouterr().err
