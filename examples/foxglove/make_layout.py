"""Writes btcap.json beside this file: a Foxglove layout for btcap recordings and the
live ``--foxglove`` server, made with the Foxglove SDK's layout API
(installed with btcap; ``python examples/foxglove/make_layout.py``).

Panels: the 3D panel (the map, the robots with their labels, the objects and the
decontamination area, seen from above, centred on the default 120 x 80 m cave), the Log
panel (``/log``), a table of the auctions, the robots' tasks over time as a State
Transitions plot (a lane per robot of the paper's full team: edit ``ROBOTS`` for another
team), and the latest closed auction whole (bids cheapest first, declines, reasons,
winner). The camera is placed by ``target_offset`` (the point it looks at, in the
followed frame); Foxglove takes ``target`` only as the followed frame's pose.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import foxglove.layouts as fl

ROBOTS = ("husky1", "spot1", "bebop1")
OUT = Path(__file__).with_name("btcap.json")


def layout() -> fl.Layout:
    scene = fl.ThreeDeePanel(
        title="cave",
        config=fl.ThreeDeeConfig(
            follow_tf="map",
            follow_mode="follow-none",
            camera_state=fl.ThreeDeeCameraState(
                perspective=False,
                distance=150.0,
                phi=0.0,
                theta_offset=0.0,
                target_offset=(60.0, 40.0, 0.0),
            ),
            topics={
                "/map": fl.BaseRendererGridTopicSettings(visible=True, color_mode="rgba-fields"),
                "/scene/areas": fl.BaseRendererSceneUpdateTopicSettings(visible=True),
                "/scene/objects": fl.BaseRendererSceneUpdateTopicSettings(visible=True),
                "/scene/robots": fl.BaseRendererSceneUpdateTopicSettings(visible=True),
            },
        ),
    )
    log = fl.LogPanel(config=fl.LogConfig(topic_to_render="/log", show_name=True))
    auctions = fl.TablePanel(title="auctions", config=fl.TableConfig(topic_path="/btcap/auctions"))
    tasks = fl.StateTransitionsPanel(
        title="timeline: what each robot does",
        config=fl.StateTransitionsConfig(
            paths=[
                fl.StateTransitionsSeries(value=f"/btcap/world.robots.{r}.task", label=r)
                for r in ROBOTS
            ],
            show_points=False,
        ),
    )
    bids = fl.RawMessagesPanel(
        title="the latest closed auction",
        config=fl.RawMessagesConfig(topic_path='/btcap/auctions{phase=="close"}', expansion="all"),
    )
    right = fl.SplitContainer(
        direction="column",
        items=[fl.SplitItem(content=p) for p in (log, auctions)],
    )
    top = fl.SplitContainer(
        items=[fl.SplitItem(proportion=3, content=scene), fl.SplitItem(proportion=2, content=right)]
    )
    bottom = fl.SplitContainer(items=[fl.SplitItem(content=tasks), fl.SplitItem(content=bids)])
    return fl.Layout(
        content=fl.SplitContainer(
            direction="column",
            items=[
                fl.SplitItem(proportion=3, content=top),
                fl.SplitItem(proportion=1, content=bottom),
            ],
        )
    )


def render() -> str:
    return json.dumps(json.loads(layout().to_json()), indent=2, sort_keys=True) + "\n"


if __name__ == "__main__":
    if sys.argv[1:] == ["--check"]:
        sys.exit(0 if OUT.read_text() == render() else f"{OUT} is not current: run {__file__}")
    OUT.write_text(render())
    print(f"wrote {OUT}")
