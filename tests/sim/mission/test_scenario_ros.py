"""A scenario's ``ros:`` block: read into the robots' ROS settings, a bad value refused in
one line naming the file and the field, and, where ROS 2 is not installed (.venv), `btcap
run` and `btcap sim serve` say how to install it in one line."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import anyio
import pytest

import btcap.cli
from btcap.cli import main
from btcap.sim.mission.scenario import ScenarioError, load_scenario
from btcap.sim.running.runner import run_fast
from btcap.team.rossettings import Qos, RosSettings

SCENARIO = """\
name: behind-ros
objects: 2
map: {cave: {width: 30, height: 20, seed: 2}}
robots:
  - {name: husky1, model: husky}
  - {name: bebop1, model: bebop}
"""

no_ros = pytest.mark.skipif(
    importlib.util.find_spec("rclpy") is not None, reason="ROS 2 is installed here"
)


@pytest.fixture(autouse=True)
def no_logging_setup(monkeypatch: pytest.MonkeyPatch) -> None:
    """main() configures structlog globally: keep the configuration as it is."""
    monkeypatch.setattr(btcap.cli, "configure_logging", lambda level, json=False: None)


def _file(tmp_path: Path, ros: str, robots: str = "") -> Path:
    path = tmp_path / "behind-ros.yaml"
    text = SCENARIO.replace("robots:\n", f"robots:\n{robots}") if robots else SCENARIO
    path.write_text(text + ros)
    return path


def test_the_block_gives_each_robot_its_settings(tmp_path: Path) -> None:
    ros = (
        "ros:\n  domain_id: 17\n  namespace: /cave/{robot}\n  node_name: agent\n"
        "  qos: {reliability: best_effort, depth: 5}\n"
    )
    s = load_scenario(_file(tmp_path, ros))
    assert s.ros is not None
    assert s.ros.settings("husky1") == RosSettings(
        domain_id=17,
        namespace="/cave/husky1",
        node_name="agent",
        qos=Qos(reliability="best_effort", depth=5),
    )
    assert s.ros.namespace_of("bebop1") == "/cave/bebop1"


def test_without_the_block_the_robots_are_reached_directly(tmp_path: Path) -> None:
    assert load_scenario(_file(tmp_path, "")).ros is None


@pytest.mark.slow
async def test_the_fast_mode_leaves_the_block_aside(tmp_path: Path) -> None:
    """A sweep runs a scenario on virtual time, which DDS cannot follow: its robots are
    reached directly, as without the block (no ROS needed)."""
    small = (Path(__file__).parents[1] / "data" / "small.yaml").read_text()
    path = tmp_path / "small.yaml"
    path.write_text(small + "ros: {namespace: '/cave/{robot}'}\n")
    with anyio.fail_after(120):
        result = await run_fast(load_scenario(path))
    assert result.completed, result.summary


@pytest.mark.parametrize(
    ("ros", "fragments"),
    [
        ("ros: {namespace: /husky}\n", ("ros.namespace", "no {robot}", "'/{robot}'")),
        ("ros: {namespace: '/9{robot}'}\n", ("ros.namespace", "no ROS 2 namespace")),
        ("ros: {node_name: 'my node'}\n", ("ros.node_name", "no ROS 2 node name")),
        ("ros: {backend: ros1, namespace: '/9{robot}'}\n", ("ros.namespace", "no ROS 1 namespace")),
        ("ros: {backend: ros1, node_name: 'my node'}\n", ("ros.node_name", "no ROS 1 node name")),
        ("ros: {domain_id: 300}\n", ("ros.domain_id", "<= 232")),
        ("ros: {qos: {reliability: sometimes}}\n", ("ros.qos.reliability", "'best_effort'")),
        ("ros: {domain: 3}\n", ("ros", "unknown field `domain`", "domain_id")),
        ("ros: {backend: ros1, master_uri: ':11311'}\n", ("ros.master_uri", "http://HOST:PORT/")),
    ],
)
def test_a_bad_value_is_one_line_naming_file_and_field(
    tmp_path: Path, ros: str, fragments: tuple[str, ...]
) -> None:
    path = _file(tmp_path, ros)
    with pytest.raises(ScenarioError) as err:
        load_scenario(path)
    line = str(err.value)
    assert "\n" not in line
    assert line.startswith(f"{path}: ")
    for fragment in fragments:
        assert fragment in line, line


def test_a_robot_whose_name_makes_no_namespace_is_named(tmp_path: Path) -> None:
    path = _file(tmp_path, "ros: {}\n", robots="  - {name: spot-1, model: spot}\n")
    with pytest.raises(ScenarioError) as err:
        load_scenario(path)
    assert str(err.value).startswith(f"{path}: robots[0].name: 'spot-1' makes no ROS 2 namespace")


def _usage(capsys: pytest.CaptureFixture[str], argv: list[str], *fragments: str) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert err.count("\n") == 1, err
    for fragment in fragments:
        assert fragment in err, err


def test_run_with_the_block_is_refused_with_fast_naming_the_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = _file(tmp_path, "ros: {}\n")
    _usage(capsys, ["run", str(path), "--fast", "--out", str(tmp_path / "o")], f"{path}: ros: ")


@pytest.mark.parametrize(
    ("ros", "flag", "label"),
    [
        ("", "--ros2", "ROS 2"),
        ("", "--ros1", "ROS 1"),
        ("ros: {backend: ros1}\n", None, "ROS 1"),
    ],
)
def test_run_refuses_a_robot_name_that_makes_no_namespace_naming_the_runs_ros(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], ros: str, flag: str | None, label: str
) -> None:
    path = _file(tmp_path, ros, robots="  - {name: spot-1, model: spot}\n")
    argv = ["run", str(path), *([flag] if flag else []), "--out", str(tmp_path / "o")]
    _usage(capsys, argv, f"robots[0].name: 'spot-1' makes no {label} namespace")


@no_ros
def test_run_with_the_block_without_ros_says_how_to_install_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = _file(tmp_path, "ros: {}\n")
    argv = ["run", str(path), "--out", str(tmp_path / "o")]
    _usage(capsys, argv, f"{path}: ros: --ros2 needs ROS 2's rclpy", "make ros-sim")


@no_ros
def test_sim_serve_without_ros_says_how_to_install_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["sim", "serve", str(_file(tmp_path, ""))]
    _usage(capsys, argv, "needs ROS 2's rclpy", "make ros-sim")
