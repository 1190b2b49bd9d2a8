"""Run a command in a network namespace of its own with only loopback up, for ROS 2 tests.

``python tests/rosnet.py CMD ARGS...`` re-runs itself under ``unshare --net`` (as root;
otherwise with ``--map-root-user``, a user namespace that maps this user to root there),
brings ``lo`` up (and lets it carry multicast, which DDS discovery uses), exports
``BTCAP_ROS_NETNS`` (the namespace's inode, so the tests can check that they are inside
it) and execs ``CMD``. The namespace has no other interface: no DDS traffic leaves the
machine, and nothing outside sees it. It dies with the command: nothing to clean up.

:func:`private` says whether this process runs in such a namespace; :func:`domain_ids`
hands out a ``ROS_DOMAIN_ID`` per test so tests inside one namespace do not see each
other either.
"""

from __future__ import annotations

import itertools
import os
import shutil
import subprocess
import sys
from collections.abc import Iterator

__all__ = ["ENV", "domain_ids", "interfaces", "private", "unavailable"]

#: Set inside the namespace to its inode.
ENV = "BTCAP_ROS_NETNS"
#: ROS 2 domain ids that map to valid UDP ports on every DDS (0-101 on Linux); 0 is
#: everybody's default, so tests start above it.
_DOMAINS = range(1, 102)


def _netns() -> int:
    return os.stat("/proc/self/ns/net").st_ino


def unavailable() -> str | None:
    """Why no private namespace can be made here, or None."""
    if not sys.platform.startswith("linux"):
        return f"network namespaces need Linux, not {sys.platform}"
    for tool in ("unshare", "ip"):
        if shutil.which(tool) is None:
            return f"no {tool!r} command (util-linux, iproute2)"
    return None


def private() -> str | None:
    """None if this process runs in a namespace made by this script with only loopback;
    else why not (a reason to skip)."""
    if os.environ.get(ENV) != str(_netns()):
        return "not inside a private network namespace: run the ROS tests with `make test-ros`"
    others = sorted(set(interfaces()) - {"lo"})
    if others:
        return f"the network namespace has interfaces besides lo: {', '.join(others)}"
    return None


def interfaces() -> list[str]:
    """The network interfaces of this process's namespace (/proc, not /sys: sysfs shows
    the namespace it was mounted in)."""
    with open("/proc/self/net/dev") as f:
        return [line.split(":", 1)[0].strip() for line in f.readlines()[2:]]


def domain_ids() -> Iterator[int]:
    """ROS domain ids for one run's tests, each once, from a start that differs by pid."""
    start = os.getpid() % len(_DOMAINS)
    order = [*_DOMAINS[start:], *_DOMAINS[:start]]
    return itertools.cycle(order)


def _inside(argv: list[str]) -> int:
    subprocess.run(["ip", "link", "set", "lo", "up"], check=True, timeout=10)
    subprocess.run(["ip", "link", "set", "lo", "multicast", "on"], check=True, timeout=10)
    os.environ[ENV] = str(_netns())
    os.execvp(argv[0], argv)


def main(argv: list[str]) -> int:
    if argv[:1] == ["--inside"]:
        return _inside(argv[1:])
    if not argv:
        print("usage: python tests/rosnet.py CMD [ARGS...]", file=sys.stderr)
        return 2
    why = unavailable()
    if why is not None:
        print(f"rosnet: cannot make a network namespace: {why}", file=sys.stderr)
        return 1
    user = [] if os.geteuid() == 0 else ["--map-root-user"]
    cmd = ["unshare", "--net", *user, "--", sys.executable, __file__, "--inside", *argv]
    return subprocess.run(cmd, check=False).returncode


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
