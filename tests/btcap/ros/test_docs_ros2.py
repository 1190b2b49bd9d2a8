"""docs/ros2.md's whole program (examples/ros2/fibonacci.py) runs and prints its result."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.ros

ROOT = Path(__file__).resolve().parents[3]


def test_the_guides_program_runs(ros_domain: int) -> None:
    done = subprocess.run(
        [sys.executable, str(ROOT / "examples" / "ros2" / "fibonacci.py")],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
        env={**os.environ, "ROS_DOMAIN_ID": str(ros_domain)},
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "succeeded: [0, 1, 1, 2, 3, 5, 8, 13, 21, 34]"
    assert (
        "It prints `succeeded: [0, 1, 1, 2, 3, 5, 8, 13, 21, 34]`"
        in (ROOT / "docs" / "ros2.md").read_text()
    )
