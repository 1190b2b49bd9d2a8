"""The simulator behind ROS 2: each simulated robot served as ROS 2 interfaces in its own
namespace (a navigation action with feedback, its operations as actions, a pose and a state
topic, a stop service), backed by the same world and simulation manager, and robots that
reach their body only through those interfaces (``btcap run --ros2``).

Nothing here imports rclpy at import time: :mod:`btcap.sim.ros2.host` loads it in a thread
before the mission starts, and only when ``--ros2`` is asked for. The interfaces are the
package ``btcap_sim_msgs`` (folder ``btcap_sim_msgs`` here), built by ``make ros-sim``.
"""

from __future__ import annotations

import importlib.util

__all__ = ["ros2_missing", "ros2_refused"]


def ros2_missing() -> str | None:
    """Why the simulator cannot go behind ROS 2 here (one line naming the fix), or None.
    Looks the modules up without importing them."""
    for module, what in (("rclpy", "ROS 2's rclpy"), ("btcap_sim_msgs", "btcap_sim_msgs")):
        if importlib.util.find_spec(module) is None:
            return (
                f"--ros2 needs {what}, which this Python does not have: run `make ros-sim` "
                "(ROS 2 Jazzy wheels and the btcap_sim_msgs interfaces, into .venv-ros) and "
                "use .venv-ros/bin/python -m btcap"
            )
    return None


def ros2_refused(*, fast: bool, distributed: bool) -> str | None:
    """Why ``btcap run --ros2`` cannot run with these options or here, or None."""
    if fast or distributed:
        return (
            "--ros2 runs the robots in this process on the wall clock: not with --fast or "
            "--distributed"
        )
    return ros2_missing()
