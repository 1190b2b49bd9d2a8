"""The simulator behind ROS 1 (as the paper set it up) against the direct simulation: the
same mission, same run.

``make bench-ros1-sim`` (``python -m btcap.bench.ros.sim1 [--quick]`` in .venv-ros1): the
paper's full-team mission on the wall clock at a speed-up, once with the robots asking the
simulation manager directly (actor messages in one process) and once with every robot
reached through ROS 1 (``run_scenario(ros1=True)``: each move a ``move_base`` goal, each
operation a service call, every position a topic message, through a rosmaster of the run's
own on loopback and a rospy process per robot and for the simulation), alternately, the
same number of times each. Reported per speed-up, as :mod:`btcap.bench.ros.sim2` does for
ROS 2: wall time and mission time of each, the ROS 1 / direct ratios of their medians,
whether every run completed with the direct run's outcome, and the load average. The ROS 1
run's wall time includes starting the master and the rospy processes (a second or two
each, in parallel) and stopping them.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import Any

from btcap.bench.ros.sim2 import cli, compare

__all__ = ["main", "run"]


def run(quick: bool = False, speedups: Sequence[float] | None = None) -> dict[str, Any]:
    speedups = speedups or ((100.0,) if quick else (50.0, 100.0))
    os.environ.setdefault("ROS_IP", "127.0.0.1")  # every rospy process on loopback
    return compare("ros1", "ros1_sim", speedups, 1 if quick else 3)


def main(argv: Sequence[str] | None = None) -> int:
    return cli(run, "python -m btcap.bench.ros.sim1", __doc__, argv)


if __name__ == "__main__":
    raise SystemExit(main())
