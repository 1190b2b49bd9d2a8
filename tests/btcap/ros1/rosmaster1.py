"""A ROS 1 master for one test: ``rosmaster --core -p PORT`` on a free loopback port.

``ROS_IP=127.0.0.1`` makes rosmaster (and every rospy node given :meth:`Master.env`) bind
its XML-RPC and TCPROS servers to loopback only, so nothing of a test is reachable from
outside the machine. Each master has its own port and its own ``ROS_HOME`` (logs), so tests
do not see each other. Leaving the ``with`` block terminates the master and reaps it.
"""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import time
import xmlrpc.client
from pathlib import Path
from types import TracebackType

__all__ = ["Master", "free_port"]

#: Readiness is a bound, not a measure: rosmaster answers in about half a second here.
READY_S = 30.0


def free_port() -> int:
    """A TCP port free on 127.0.0.1 now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


class Master:
    """One rosmaster process; ``uri`` is its ``ROS_MASTER_URI``."""

    def __init__(self, home: Path) -> None:
        self.home = home
        self.port = free_port()
        self.uri = f"http://127.0.0.1:{self.port}/"
        self.process: subprocess.Popen[bytes] | None = None

    @staticmethod
    def executable() -> str | None:
        return shutil.which("rosmaster", path=f"{os.environ.get('PATH', '')}:/usr/bin")

    def env(self) -> dict[str, str]:
        """The environment of a ROS 1 process on this master, on loopback."""
        env = {k: v for k, v in os.environ.items() if not k.startswith("ROS_")}
        env.update(
            ROS_MASTER_URI=self.uri,
            ROS_IP="127.0.0.1",
            ROS_HOME=str(self.home),
            ROS_LOG_DIR=str(self.home / "log"),
        )
        return env

    def proxy(self) -> xmlrpc.client.ServerProxy:
        return xmlrpc.client.ServerProxy(self.uri)

    def __enter__(self) -> Master:
        exe = self.executable()
        if exe is None:
            raise RuntimeError("rosmaster is not installed (Debian's python3-rosmaster)")
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
                raise RuntimeError(f"rosmaster on port {self.port} exited: {err.strip()}")
            try:
                with self.proxy() as proxy:
                    code, _, _ = proxy.getPid("/btcap_test")
                if code == 1:
                    return
            except OSError:
                pass
            if time.monotonic() > deadline:
                raise RuntimeError(f"rosmaster on port {self.port}: no answer in {READY_S} s")
            time.sleep(0.05)

    def stop(self) -> None:
        """Terminate the master (kill it if it does not go) and reap it. Idempotent."""
        process = self.process
        if process is None or process.returncode is not None:
            return
        process.terminate()
        try:
            process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
        if process.stderr is not None:
            process.stderr.close()

    def __exit__(
        self, et: type[BaseException] | None, e: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.stop()
