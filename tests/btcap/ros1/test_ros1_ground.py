"""The ROS 1 tests' ground: Debian's rospy imports beside the project's locked packages,
and a real rosmaster of the test's own carries a real rospy topic on loopback."""

from __future__ import annotations

import io
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from rosmaster1 import Master

pytestmark = pytest.mark.ros1

DEBIAN_SITE = "/usr/lib/python3/dist-packages"


def test_rospy_comes_from_debian_and_the_locked_packages_from_the_venv() -> None:
    import msgspec
    import rospy

    assert rospy.__file__ is not None
    assert rospy.__file__.startswith(DEBIAN_SITE)
    assert msgspec.__file__ is not None
    assert not msgspec.__file__.startswith(DEBIAN_SITE)
    venv_site = str(Path(msgspec.__file__).parent.parent)  # .venv's site-packages
    assert sys.path.index(venv_site) < sys.path.index(DEBIAN_SITE)


def _listening(port: int) -> list[str]:
    """Local addresses (hex, as /proc/net/tcp writes them) listening on ``port``."""
    found = []
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        for line in Path(table).read_text().splitlines()[1:]:
            local, state = line.split()[1], line.split()[3]
            address, hexport = local.split(":")
            if state == "0A" and int(hexport, 16) == port:
                found.append(address)
    return found


def test_the_master_answers_on_loopback_only_and_is_gone_after(tmp_path: Path) -> None:
    with Master(tmp_path) as m, m.proxy() as proxy:
        code, _, state = proxy.getSystemState("/btcap_test")
        assert code == 1
        assert state == [[], [], []]  # --core: no rosout, nothing registered
        assert _listening(m.port) == ["0100007F"]  # 127.0.0.1
    assert m.process is not None
    assert m.process.returncode is not None
    assert _listening(m.port) == []


#: A rospy node that publishes on a topic it also subscribes to and prints what came back.
_ROUND_TRIP = textwrap.dedent(
    """
    import threading, rospy
    from std_msgs.msg import String
    got = threading.Event()
    rospy.init_node("btcap_round_trip", disable_signals=True)
    rospy.Subscriber("/chatter", String, lambda m: (print(m.data, flush=True), got.set()))
    pub = rospy.Publisher("/chatter", String, queue_size=1, latch=True)
    pub.publish(String(data="hello over ROS 1"))
    ok = got.wait(30)
    rospy.signal_shutdown("done")
    raise SystemExit(0 if ok else 1)
    """
)


def test_a_rospy_node_round_trips_a_topic_through_the_tests_master(master: Master) -> None:
    out = subprocess.run(
        [sys.executable, "-c", _ROUND_TRIP],
        env=master.env(),
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.splitlines() == ["hello over ROS 1"]


def test_genpy_makes_a_message_type_without_a_build() -> None:
    from genpy.dynamic import generate_dynamic

    types = generate_dynamic("btcap_test/Count", "int32 n\nstring label\n")
    count_type = types["btcap_test/Count"]
    buf = io.BytesIO()
    count_type(n=7, label="seven").serialize(buf)
    back = count_type().deserialize(buf.getvalue())
    assert (back.n, back.label) == (7, "seven")
