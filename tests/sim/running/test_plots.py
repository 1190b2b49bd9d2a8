"""The timeline plot of a mission result, from a hand-made result."""

from __future__ import annotations

from pathlib import Path

import pytest

from btcap.sim.running.metrics import Interval, Mark, MissionResult, RobotStats
from btcap.sim.running.plots import plot_comparison, plot_timeline

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def result(timeline: list[Interval], marks: list[Mark], time_s: float = 600.0) -> MissionResult:
    stats = RobotStats("husky", 100.0, 600.0, 0.17, {"explore": 1}, 42.0)
    return MissionResult(
        scenario="hand-made",
        completed=True,
        mission_time_s=time_s,
        summary={"objects": 2.0, "found": 2.0, "decontaminated": 1.0},
        robots={"husky1": stats, "bebop1": RobotStats("bebop", 10.0, 300.0, 0.03, {}, 5.0)},
        auctions=3,
        executions_lost=1,
        reassigned=1,
        robot_failures=1,
        robots_left=0,
        assignments={"mission/explore": ["husky1", "bebop1"]},
        timeline=timeline,
        marks=marks,
    )


def read_png(path: Path) -> tuple[int, int]:
    from matplotlib import image

    data = path.read_bytes()
    assert data.startswith(PNG_MAGIC)
    assert len(data) > 5_000
    pixels = image.imread(path)
    return int(pixels.shape[0]), int(pixels.shape[1])


def test_plot_timeline_writes_a_png(tmp_path: Path) -> None:
    import matplotlib.pyplot as plt

    timeline = [
        Interval("husky1", "move", 0.0, 30.0, True),
        Interval("husky1", "explore", 30.0, 90.0, True, target=0),
        Interval("husky1", "identify", 90.0, 150.0, False, target=3),  # failed: hatched
        Interval("bebop1", "decontaminate", 200.0, 260.0, True, target=1),
        Interval("bebop1", "dance", 300.0, 320.0, True),  # unknown kinds get a grey bar
        Interval("ghost", "explore", 0.0, 10.0, True),  # not a robot of the result
        Interval("bebop1", "explore", 50.0, 50.0, True),  # empty: skipped
    ]
    marks = [
        Mark(-3.0, "joined", "husky1"),  # before the start: drawn at 0
        Mark(100.0, "joined", "bebop1"),
        Mark(200.0, "down", "husky1"),
        Mark(250.0, "failed", "husky1"),
        Mark(400.0, "up", "husky1"),
        Mark(500.0, "left", "bebop1"),
        Mark(510.0, "changed", "bebop1"),  # not a mark kind: ignored
    ]
    out = plot_timeline(result(timeline, marks), tmp_path / "timeline.png")
    assert out == tmp_path / "timeline.png"
    height, width = read_png(out)
    assert width > height > 100
    assert not plt.get_fignums()  # the figure was closed


@pytest.mark.parametrize("time_s", [0.0, 600.0])
def test_plot_timeline_of_an_empty_result(tmp_path: Path, time_s: float) -> None:
    out = plot_timeline(result([], [], time_s), str(tmp_path / "empty.png"))
    read_png(out)


def test_plot_timeline_survives_a_json_round_trip(tmp_path: Path) -> None:
    import msgspec

    original = result([Interval("husky1", "explore", 0.0, 60.0, True, 0)], [])
    again = msgspec.json.decode(original.to_json(), type=MissionResult)
    assert again == original
    read_png(plot_timeline(again, tmp_path / "t.png"))


def test_plot_comparison_of_missions_with_different_robots(tmp_path: Path) -> None:
    import matplotlib.pyplot as plt
    import msgspec

    done = result([], [], 600.0)
    unfinished = msgspec.structs.replace(
        done,
        scenario="lonely",
        completed=False,
        mission_time_s=2000.0,
        robots={"spot1": RobotStats("spot", 5.0, 2000.0, 0.0, {}, 0.0)},
    )
    empty = msgspec.structs.replace(done, scenario="nobody", robots={})
    out = plot_comparison([done, unfinished, empty], tmp_path / "compare.png")
    height, width = read_png(out)
    assert width > height > 100
    assert not plt.get_fignums()
