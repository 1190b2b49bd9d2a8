"""Loading rclpy, once, with the reason in one line when it cannot be loaded.

The only module of the bridge that imports ROS at its top is the one that needs it
(:mod:`btcap.ros.client`); it is imported through :func:`load`, which turns a missing
ROS into :class:`~btcap.ros.errors.RosMissing` and imports, with their warnings silenced,
the modules of the wheels that warn on import (lark-parser 0.12 imports the deprecated
``sre_parse``; rclpy imports it on a node's first publisher), so a program run with
``-W error`` is not stopped by them.
"""

from __future__ import annotations

import importlib
import warnings
from types import ModuleType

from btcap.ros.errors import RosMissing

__all__ = ["load"]


def load() -> ModuleType:
    """``rclpy``, imported (RosMissing if it cannot be)."""
    try:
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", category=DeprecationWarning)
            rclpy = importlib.import_module("rclpy")
            importlib.import_module("rclpy.action")
            importlib.import_module("rosidl_generator_py")
    except ImportError as exc:
        raise RosMissing(f"ROS 2 (rclpy: {exc})") from None
    return rclpy
