"""A real ROS 1 publisher for the bridge's tests, in a rospy process of its own
(``python talkers1.py NODE TYPE TOPIC``, with a test master's environment and
``ROS_NAMESPACE``): publishes a default ``TYPE`` message on ``TOPIC`` every 50 ms, says
``up`` on stdout once registered, and ends when stdin closes."""

from __future__ import annotations

import importlib
import sys
import threading

import rospy


def main(node: str, type_name: str, topic: str) -> None:
    package, name = type_name.split("/")
    cls = getattr(importlib.import_module(f"{package}.msg"), name)
    rospy.init_node(node, disable_signals=True)
    pub = rospy.Publisher(topic, cls, queue_size=1)
    done = threading.Event()

    def talk() -> None:
        while not done.wait(0.05):
            pub.publish(cls())

    threading.Thread(target=talk, daemon=True).start()
    sys.stdout.write("up\n")
    sys.stdout.flush()
    sys.stdin.read()  # until the test closes it
    done.set()
    rospy.signal_shutdown("test over")


if __name__ == "__main__":
    main(*sys.argv[1:4])
