"""The README's quickstart: a tree in Python (the same tree as trees/quickstart.yaml)."""

import asyncio

from btcap import Constant, Log, Retry, Sequence, Timeout, Tree, Wait


def build() -> Tree:
    goal = Constant("goal", value=(3.0, 4.0), type=tuple[float, float])
    report = Log("report", message="arrived")
    leg = Timeout("leg", seconds=5.0, children=[Wait("drive", seconds=0.2)])
    tree = Tree(
        Sequence(
            "go_and_report", children=[goal, Retry("retry", retries=2, children=[leg]), report]
        )
    )
    tree.wire(goal, "value", report, "value")  # type-checked here, not at run time
    return tree


if __name__ == "__main__":
    print(asyncio.run(build().run(rate_hz=20)))  # State.SUCCEEDED
