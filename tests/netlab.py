"""A private network for tests: Linux network namespaces joined by veth pairs to a bridge.

:class:`Lab` makes one namespace per host plus a hub namespace holding a bridge; each
host's ``eth0`` is one end of a veth pair whose other end (``p-HOST``) is a port of the
bridge. Hosts get ``10.77.0.N/24``: the addresses exist only inside these namespaces.
Everything is made inside the lab's own namespaces (the host's interfaces and routes are
never touched) under names unique to the run (``btcap-tPIDNS-PID-RANDOM-HOST``), so
parallel runs never collide; :meth:`Lab.close` deletes the namespaces, and with them the
veths and the bridge. A run that was killed before it could clean up is swept by the next
one: namespaces of this pid namespace whose creating process is gone are deleted.

Needs root on Linux and ``ip`` (iproute2); :func:`unavailable` says why not, for a skip.
"""

from __future__ import annotations

import os
import re
import secrets
import shutil
import subprocess
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field

__all__ = ["Lab", "LabUnavailable", "unavailable"]

_PREFIX = "btcap-t"
_SUBNET = "10.77.0"
#: Each ip command is bounded; they take milliseconds.
_IP_TIMEOUT_S = 10.0


class LabUnavailable(Exception):
    """This machine cannot make the lab (the message says why): a reason to skip."""


def unavailable() -> str | None:
    """Why no lab can be made here, or None."""
    if not sys.platform.startswith("linux"):
        return f"network namespaces need Linux, not {sys.platform}"
    if os.geteuid() != 0:
        return "network namespaces need root"
    if shutil.which("ip") is None:
        return "no 'ip' command (iproute2)"
    return None


def _pid_namespace() -> str:
    return str(os.stat("/proc/self/ns/pid").st_ino)


def ip(*args: str, check: bool = True) -> subprocess.CompletedProcess[str]:
    """Run ``ip ARGS``; a failure raises CalledProcessError with what ip said."""
    return subprocess.run(
        ["ip", *args], capture_output=True, text=True, timeout=_IP_TIMEOUT_S, check=check
    )


def sweep() -> list[str]:
    """Delete lab namespaces left by dead runs of this pid namespace; their names."""
    listed = ip("netns", "list", check=False).stdout.split("\n")
    mine = re.compile(rf"^{re.escape(_PREFIX)}{_pid_namespace()}-(\d+)-")
    gone = []
    for line in listed:
        name = line.split(" ", 1)[0]
        m = mine.match(name)
        if m is not None and not os.path.exists(f"/proc/{m.group(1)}"):
            ip("netns", "delete", name, check=False)
            gone.append(name)
    return gone


@dataclass
class Lab:
    """Hosts on one bridge, each in its own namespace; see the module docstring."""

    hosts: Sequence[str]
    token: str = field(
        default_factory=lambda: f"{_PREFIX}{_pid_namespace()}-{os.getpid()}-{secrets.token_hex(3)}"
    )
    namespaces: list[str] = field(default_factory=list)
    cut_how: dict[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if len(self.hosts) > 200 or not all(re.fullmatch(r"[a-z]{1,12}", h) for h in self.hosts):
            raise ValueError(f"hosts {self.hosts!r}: up to 200 names of 1-12 lowercase letters")

    @property
    def hub(self) -> str:
        return f"{self.token}-hub"

    def namespace(self, host: str) -> str:
        return f"{self.token}-{host}"

    def address(self, host: str) -> str:
        return f"{_SUBNET}.{list(self.hosts).index(host) + 1}"

    def prefix(self, host: str) -> list[str]:
        """The command prefix that runs a program inside ``host``'s namespace."""
        return ["ip", "netns", "exec", self.namespace(host)]

    def _add_namespace(self, name: str) -> None:
        ip("netns", "add", name)
        self.namespaces.append(name)
        ip("-n", name, "link", "set", "lo", "up")

    def open(self) -> Lab:
        """Make the namespaces, the bridge and the veths, every link up. Raises
        :class:`LabUnavailable` if this kernel or container cannot (nothing is left)."""
        sweep()
        try:
            self._add_namespace(self.hub)
        except (subprocess.CalledProcessError, OSError) as exc:
            self.close()
            said = getattr(exc, "stderr", "") or str(exc)
            raise LabUnavailable(f"'ip netns add' failed: {said.strip()}") from None
        try:
            # ip netns exec remounts /sys: a container may allow namespaces but not that.
            ip("netns", "exec", self.hub, sys.executable, "-c", "pass")
            ip("-n", self.hub, "link", "add", "br0", "type", "bridge")
            ip("-n", self.hub, "link", "set", "br0", "up")
            for host in self.hosts:
                ns, port = self.namespace(host), f"p-{host}"
                self._add_namespace(ns)
                # Made inside the host's namespace with its peer in the hub's: neither end
                # ever exists in the namespace this test runs in.
                veth = f"link add eth0 type veth peer name {port} netns {self.hub}"
                ip("-n", ns, *veth.split())
                ip("-n", self.hub, "link", "set", port, "master", "br0")
                ip("-n", self.hub, "link", "set", port, "up")
                ip("-n", ns, "addr", "add", f"{self.address(host)}/24", "dev", "eth0")
                ip("-n", ns, "link", "set", "eth0", "up")
        except (subprocess.CalledProcessError, OSError) as exc:
            self.close()
            said = getattr(exc, "stderr", "") or str(exc)
            why = f"cannot run programs in it or make veths and a bridge: {said.strip()}"
            raise LabUnavailable(why) from None
        return self

    def cut(self, host: str, how: str = "down") -> None:
        """Cut ``host`` off from everyone, silently for its programs: ``down`` takes its
        bridge port down (its eth0 loses carrier), ``detach`` takes the port out of the
        bridge (eth0 stays up; frames go nowhere)."""
        port = f"p-{host}"
        if how == "down":
            ip("-n", self.hub, "link", "set", port, "down")
        elif how == "detach":
            ip("-n", self.hub, "link", "set", port, "nomaster")
        else:
            raise ValueError(f"how: {how!r}, expected 'down' or 'detach'")
        self.cut_how[host] = how

    def heal(self, host: str) -> None:
        """Undo :meth:`cut`."""
        how = self.cut_how.pop(host)
        port = f"p-{host}"
        if how == "down":
            ip("-n", self.hub, "link", "set", port, "up")
        else:
            ip("-n", self.hub, "link", "set", port, "master", "br0")

    def close(self) -> None:
        """Delete every namespace made (their veths and bridge go with them). Programs
        still running inside must be ended first, or they keep theirs alive."""
        while self.namespaces:
            ip("netns", "delete", self.namespaces.pop(), check=False)

    def __enter__(self) -> Lab:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()
