"""The mission timeline as a picture: a lane per robot, like the paper's figures 4 and 5."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from btcap.sim.running.metrics import MissionResult

__all__ = ["plot_comparison", "plot_timeline"]

_COLOURS = {
    "move": "#c8c8c8",
    "explore": "#4c72b0",
    "identify": "#dd8452",
    "decontaminate": "#55a868",
}
_MARKS = {
    "joined": ("^", "#2ca02c"),
    "left": ("v", "#7f7f7f"),
    "failed": ("x", "#d62728"),
    "down": ("X", "#d62728"),
    "up": ("P", "#2ca02c"),
    "crashed": ("*", "#000000"),
}


def plot_timeline(result: MissionResult, path: str | Path) -> Path:
    """Write a PNG of who ran what and when, with join/leave/fail marks."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    robots = list(result.robots)
    lane = {r: i for i, r in enumerate(robots)}
    fig, ax = plt.subplots(figsize=(12, 1.0 + 0.7 * len(robots)), dpi=110)
    for iv in result.timeline:
        if iv.robot not in lane or iv.end <= iv.start:
            continue
        y = lane[iv.robot]
        height = 0.35 if iv.kind == "move" else 0.7
        ax.broken_barh(
            [(iv.start, iv.end - iv.start)],
            (y - height / 2, height),
            facecolors=_COLOURS.get(iv.kind, "#999999"),
            edgecolor="black" if iv.kind != "move" else "none",
            linewidth=0.4,
            hatch=None if iv.ok else "//",
        )
        if iv.kind != "move" and iv.target >= 0 and iv.end - iv.start > result.mission_time_s / 80:
            ax.text(
                (iv.start + iv.end) / 2, y, str(iv.target), ha="center", va="center", fontsize=6
            )
    for m in result.marks:
        if m.robot in lane and m.event in _MARKS:
            marker, colour = _MARKS[m.event]
            ax.plot([max(0.0, m.time)], [lane[m.robot] + 0.45], marker=marker, color=colour, ms=7)
    ax.set_yticks(range(len(robots)))
    ax.set_yticklabels([f"{r} ({result.robots[r].model})" for r in robots])
    ax.set_ylim(-0.6, len(robots) - 0.2)
    ax.set_xlim(0, max(1.0, result.mission_time_s))
    ax.set_xlabel("mission time [s]")
    ax.set_title(
        f"{result.scenario}: {result.mission_time_s:.0f} s, "
        f"{'completed' if result.completed else 'NOT completed'}"
    )
    handles = [Patch(facecolor=c, label=k) for k, c in _COLOURS.items()]
    handles.append(Patch(facecolor="white", edgecolor="black", hatch="//", label="failed"))
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.25), ncol=5, fontsize=8)
    ax.grid(axis="x", alpha=0.3)
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out)
    plt.close(fig)
    return out


def plot_comparison(results: Sequence[MissionResult], path: str | Path) -> Path:
    """Write a PNG comparing missions side by side (``btcap run --compare``): the mission
    time of each (hatched if it did not complete) and how busy each of its robots was."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    names = [r.scenario for r in results]
    fig, (ax_time, ax_busy) = plt.subplots(
        1, 2, figsize=(4.0 + 2.2 * len(results), 4.5), dpi=110, width_ratios=[1, 2]
    )
    for i, r in enumerate(results):
        ax_time.bar(
            i,
            r.mission_time_s,
            color="#4c72b0",
            edgecolor="black",
            linewidth=0.4,
            hatch=None if r.completed else "//",
        )
        label = f"{r.mission_time_s:.0f} s" + ("" if r.completed else "\nNOT completed")
        ax_time.text(i, r.mission_time_s, label, ha="center", va="bottom", fontsize=8)
    ax_time.set_xticks(range(len(names)), names, rotation=20, ha="right")
    ax_time.set_ylabel("mission time [s]")
    ax_time.margins(y=0.15)
    models = sorted({st.model for r in results for st in r.robots.values()})
    colour = {m: plt.get_cmap("tab10")(k % 10) for k, m in enumerate(models)}
    for i, r in enumerate(results):
        width = min(0.25, 0.8 / max(1, len(r.robots)))
        left = i - width * len(r.robots) / 2
        for j, (robot, st) in enumerate(r.robots.items()):
            x = left + width * (j + 0.5)
            ax_busy.bar(x, 100 * st.utilisation, width, color=colour[st.model], edgecolor="black")
            ax_busy.text(x, 1, robot, rotation=90, ha="center", va="bottom", fontsize=7)
    ax_busy.set_xticks(range(len(names)), names, rotation=20, ha="right")
    ax_busy.set_ylabel("utilisation [%]")
    ax_busy.set_ylim(0, 119)
    ax_busy.legend(
        handles=[Patch(facecolor=colour[m], label=m) for m in models],
        loc="upper center",
        ncol=len(models),
        fontsize=8,
    )
    for ax in (ax_time, ax_busy):
        ax.grid(axis="y", alpha=0.3)
    fig.suptitle("mission comparison")
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out)
    plt.close(fig)
    return out
