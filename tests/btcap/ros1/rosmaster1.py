"""A ROS 1 master for one test: the product's run master
(:class:`~btcap.sim.ros1.master.RunMaster`, ``rosmaster --core -p PORT`` on a free
loopback port) with the test's own ``ROS_HOME`` and an environment of no ``ROS_`` variable
of the caller's.

``ROS_IP=127.0.0.1`` makes rosmaster (and every rospy node given :meth:`Master.env`) bind
its XML-RPC and TCPROS servers to loopback only, so nothing of a test is reachable from
outside the machine. Each master has its own port and its own ``ROS_HOME`` (logs), so tests
do not see each other. Leaving the ``with`` block terminates the master and reaps it.
"""

from __future__ import annotations

import os
import xmlrpc.client
from pathlib import Path
from types import TracebackType

from btcap.sim.ros1.master import READY_S, RunMaster, free_port

__all__ = ["READY_S", "Master", "free_port"]


class Master(RunMaster):
    """One rosmaster process; ``uri`` is its ``ROS_MASTER_URI``, its logs in ``home``."""

    def __init__(self, home: Path) -> None:
        super().__init__(str(home))

    def env(self) -> dict[str, str]:
        """The environment of a ROS 1 process on this master, on loopback."""
        env = {k: v for k, v in os.environ.items() if not k.startswith("ROS_")}
        env.update(
            ROS_MASTER_URI=self.uri,
            ROS_IP="127.0.0.1",
            ROS_HOME=self.home,
            ROS_LOG_DIR=os.path.join(self.home, "log"),
        )
        return env

    def proxy(self) -> xmlrpc.client.ServerProxy:
        return xmlrpc.client.ServerProxy(self.uri)

    def __enter__(self) -> Master:
        self.start()
        return self

    def __exit__(
        self, et: type[BaseException] | None, e: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.stop()
