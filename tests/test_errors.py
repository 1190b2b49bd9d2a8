"""Every error btcap raises on purpose is a BtcapError, and keeps its builtin base."""

from __future__ import annotations

import importlib
import importlib.util
import inspect
import warnings

import pytest
from btcap_sources import modules

from btcap import BtcapError

#: The simulator's ROS 2 side imports rclpy's messages at its top: walked only where ROS 2
#: is installed (``make test-ros`` runs no walk; an import of them without it is refused
#: by ``btcap run --ros2`` before they load).
NEEDS_ROS = {"btcap.sim.ros2.client", "btcap.sim.ros2.server"}
HAS_ROS = importlib.util.find_spec("rclpy") is not None


def _exceptions() -> dict[str, type[Exception]]:
    """The public exception classes defined in btcap's modules, by qualified name."""
    found: dict[str, type[Exception]] = {}
    for dotted in modules():  # the mapped folders too (actors/ is btcap.actors)
        if dotted.rpartition(".")[2] == "__main__":  # running it is running the CLI
            continue
        if dotted in NEEDS_ROS and not HAS_ROS:
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)
            module = importlib.import_module(dotted)
        for name, value in vars(module).items():
            if (
                inspect.isclass(value)
                and issubclass(value, Exception)
                and not issubclass(value, Warning)  # warnings have BtcapWarning
                and value.__module__ == module.__name__
                and not name.startswith("_")
            ):
                found[f"{module.__name__}.{name}"] = value
    return found


EXCEPTIONS = _exceptions()


def test_the_walk_sees_the_errors_of_every_layer() -> None:
    assert {
        "btcap.transports.codec.CodecError",
        "btcap.actors.errors.AskTimeout",
        "btcap.bt.state.TreeError",
        "btcap.team.deployment.launch.AgentFailed",
        "btcap.cli.CliError",
        "btcap.sim.mission.scenario.ScenarioError",
    } <= EXCEPTIONS.keys()


def test_every_error_btcap_defines_is_a_btcap_error() -> None:
    stray = sorted(name for name, cls in EXCEPTIONS.items() if not issubclass(cls, BtcapError))
    assert not stray, f"not BtcapError subclasses: {stray}"


@pytest.mark.parametrize(
    ("name", "builtin"),
    [
        ("btcap.transports.codec.CodecError", ValueError),
        ("btcap.actors.errors.AskTimeout", TimeoutError),
        ("btcap.bt.state.TreeTimeout", TimeoutError),
        ("btcap.bt.files.btcpp_nodes.MappingError", ValueError),
        ("btcap.bt.invariants.HaltingViolation", AssertionError),
        ("btcap.monitor.record.RecordError", ValueError),
        ("btcap.sim.world.grid.MapError", ValueError),
        ("btcap.sim.world.model.TeamFileError", ValueError),
        ("btcap.sim.mission.scenario.ScenarioError", ValueError),
    ],
)
def test_errors_keep_their_builtin_base(name: str, builtin: type[Exception]) -> None:
    """``except ValueError`` (or ``TimeoutError`` ...) written before BtcapError still works."""
    assert issubclass(EXCEPTIONS[name], builtin)
