"""The timeline of a recording as a PNG: a lane per robot with what it ran for whom,
hatched where a run did not succeed, and the joins, leaves and failures the monitor saw.
Drawn from the same events as the page (``btcap replay FILE --plot OUT.png``)."""

from __future__ import annotations

from pathlib import Path

from btcap.monitor.view import Event, TeamView

__all__ = ["plot_record"]

_MARKS = {"joined": ("^", "#2ca02c"), "left": ("v", "#7f7f7f"), "failed": ("x", "#d62728")}


def plot_record(events: list[Event], path: str | Path, *, title: str = "") -> Path:
    """Write the timeline of ``events`` (a recording's, in order) to ``path``: a lane per
    robot that ran something (the last :data:`~btcap.monitor.view.MAX_RUNS` runs)."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    view = TeamView()
    for ev in events:
        view.apply(ev)
    runs = list(view.runs.values())
    robots = sorted({r["robot"] for r in runs})
    lane = {r: i for i, r in enumerate(robots)}
    caps = sorted({r["capability"] for r in runs})
    colour = {c: plt.get_cmap("tab10")(k % 10) for k, c in enumerate(caps)}
    start = min([float(e["t"]) for e in events], default=0.0)
    fig, ax = plt.subplots(figsize=(12, 1.2 + 0.6 * max(1, len(robots))), dpi=110)
    for r in runs:
        end = r["end"] if r["end"] is not None else view.t
        ax.broken_barh(
            [(r["start"] - start, max(end - r["start"], 1e-9))],
            (lane[r["robot"]] - 0.35, 0.7),
            facecolors=colour[r["capability"]],
            edgecolor="black",
            linewidth=0.4,
            hatch=None if r["result"] in (None, "succeeded") else "//",
        )
    for m in view.marks:
        if m["robot"] in lane and m["change"] in _MARKS:
            marker, c = _MARKS[m["change"]]
            ax.plot([m["t"] - start], [lane[m["robot"]] + 0.45], marker=marker, color=c, ms=7)
    ax.set_yticks(range(len(robots)), robots)
    ax.set_ylim(-0.6, max(1, len(robots)) - 0.2)
    ax.set_xlim(0, max(1.0, view.t - start))
    ax.set_xlabel("time [s]")
    ax.set_title(title or f"{len(runs)} runs, {len(view.auctions)} auctions")
    handles = [Patch(facecolor=colour[c], label=c) for c in caps]
    handles.append(Patch(facecolor="white", edgecolor="black", hatch="//", label="cut short"))
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.3), ncol=6, fontsize=8)
    ax.grid(axis="x", alpha=0.3)
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out)
    plt.close(fig)
    return out
