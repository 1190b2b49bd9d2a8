"""A ROS 1 master of the run's own: ``rosmaster --core -p PORT`` on a free loopback port,
for ``btcap run --ros1`` without a ``master_uri`` (a run needs one, and should not take
over a master someone else runs).

``ROS_IP=127.0.0.1`` binds it (and every rospy process given :meth:`RunMaster.env`) to
loopback; its logs go to a temporary ``ROS_HOME`` removed with it.
"""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import tempfile
import time

from btcap.errors import BtcapError
from btcap.ros import rpc1

__all__ = ["RunMaster", "RunMasterError", "free_port", "ros_env"]

#: A bound, not a measure: rosmaster answers in about half a second here.
READY_S = 30.0
#: ... and each of its asks whether it is up.
ASK_S = 2.0


class RunMasterError(BtcapError, RuntimeError):
    """The run's own rosmaster could not be started."""


def ros_env(master_uri: str, home: str | None = None) -> dict[str, str]:
    """This process's environment for a ROS 1 process on ``master_uri``, on loopback unless
    ``ROS_IP``/``ROS_HOSTNAME`` say otherwise."""
    env = dict(os.environ, ROS_MASTER_URI=master_uri)
    if "ROS_IP" not in env and "ROS_HOSTNAME" not in env:
        env["ROS_IP"] = "127.0.0.1"
    if home is not None:
        env.update(ROS_HOME=home, ROS_LOG_DIR=os.path.join(home, "log"))
    return env


def free_port() -> int:
    """A TCP port free on 127.0.0.1 now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


class RunMaster:
    """One rosmaster process, started by :meth:`start` and stopped by :meth:`stop` (both
    block: a thread); ``uri`` is its ``ROS_MASTER_URI``. Its logs go to ``home``, else to
    a temporary folder removed by :meth:`stop` (the ROS 1 tests' master passes its own)."""

    def __init__(self, home: str | None = None) -> None:
        self.port = free_port()
        self.uri = f"http://127.0.0.1:{self.port}/"
        self._own_home = home is None
        self.home = tempfile.mkdtemp(prefix="btcap-rosmaster-") if home is None else home
        self.process: subprocess.Popen[bytes] | None = None

    @staticmethod
    def executable() -> str | None:
        """The ``rosmaster`` to run (Debian's python3-rosmaster), or None."""
        return shutil.which("rosmaster", path=f"{os.environ.get('PATH', '')}:/usr/bin")

    def env(self) -> dict[str, str]:
        """The master's environment: :func:`ros_env`, on loopback."""
        env = ros_env(self.uri, self.home)
        env["ROS_IP"] = "127.0.0.1"
        return env

    def start(self) -> RunMaster:
        exe = self.executable()
        if exe is None:
            raise RunMasterError(
                "--ros1 needs a ROS 1 master: Debian's python3-rosmaster is not installed "
                "(`make ros1`), or give the scenario's ros.master_uri"
            )
        self.process = subprocess.Popen(
            [exe, "--core", "-p", str(self.port)],
            env=self.env(),
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
        )
        try:
            self._wait_ready()
        except BaseException:
            self.stop()
            raise
        return self

    def _wait_ready(self) -> None:
        assert self.process is not None
        deadline = time.monotonic() + READY_S
        while True:
            if self.process.poll() is not None:
                err = self.process.stderr.read().decode() if self.process.stderr else ""
                why = err.strip().splitlines()[-1] if err.strip() else "no message"
                raise RunMasterError(f"rosmaster on port {self.port} exited: {why}")
            try:
                rpc1.call(self.uri, "getPid", "/btcap_run", timeout_s=ASK_S)
                return
            except rpc1.RosCallError:  # not listening yet (or not answering: asked again)
                pass
            if time.monotonic() > deadline:
                raise RunMasterError(f"rosmaster on port {self.port}: no answer in {READY_S} s")
            time.sleep(0.05)

    def stop(self) -> None:
        """Terminate the master (kill it if it does not go), reap it, remove its logs
        (unless ``home`` was given). Idempotent."""
        process = self.process
        if process is not None and process.returncode is None:
            process.terminate()
            try:
                process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        if process is not None and process.stderr is not None:
            process.stderr.close()
        if self._own_home:
            shutil.rmtree(self.home, ignore_errors=True)
