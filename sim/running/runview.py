"""What ``btcap run`` shows: a progress line or live table while a mission runs, and the
summary at its end (rich is imported when one is drawn, so ``--help`` stays fast)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from rich.console import Group
    from rich.table import Table

    from btcap.sim.running.metrics import MissionResult
    from btcap.sim.running.runner import Progress

__all__ = ["progress_line", "progress_view", "summary_table"]


def progress_line(p: Progress, name: str) -> str:
    """The live table as one plain line, for logs."""
    s = p.summary
    robots = ", ".join(
        f"{robot} {p.tasks.get(robot, 'idle') if up else 'away'}" for robot, up in p.present.items()
    )
    return (
        f"{name} t={p.time:.0f} s: found {s.get('found', 0):.0f}/{s.get('objects', 0):.0f}, "
        f"identified {s.get('identified', 0):.0f}, decontaminated "
        f"{s.get('decontaminated', 0):.0f}, explored {100 * float(s.get('coverage', 0)):.0f}%; "
        f"{robots}"
    )


def progress_view(p: Progress, name: str) -> Table:
    from rich.table import Table

    t = Table(title=f"{name} - t = {p.time:7.0f} s", expand=False)
    t.add_column("robot")
    t.add_column("status")
    t.add_column("current task")
    for robot, present in p.present.items():
        t.add_row(robot, "up" if present else "[red]away[/red]", p.tasks.get(robot, "-"))
    s = p.summary
    t.caption = (
        f"found {s.get('found', 0)}/{s.get('objects', 0)}  identified {s.get('identified', 0)}  "
        f"contaminated {s.get('contaminated', 0)}  decontaminated {s.get('decontaminated', 0)}  "
        f"explored {100 * float(s.get('coverage', 0)):.0f}%"
    )
    return t


def summary_table(results: list[MissionResult]) -> Group:
    from rich.console import Group
    from rich.table import Table
    from rich.text import Text

    head = Table(title="mission summary")
    head.add_column("")
    for r in results:
        head.add_column(r.scenario, justify="right")
    rows: list[tuple[str, list[str]]] = [
        ("completed", ["yes" if r.completed else "NO" for r in results]),
        ("mission time [s]", [f"{r.mission_time_s:.0f}" for r in results]),
        (
            "objects found",
            [f"{r.summary['found']:.0f}/{r.summary['objects']:.0f}" for r in results],
        ),
        ("decontaminated", [f"{r.summary['decontaminated']:.0f}" for r in results]),
        ("auctions", [str(r.auctions) for r in results]),
        ("executions lost", [str(r.executions_lost) for r in results]),
        ("re-assigned", [str(r.reassigned) for r in results]),
        ("moved (cheaper)", [str(r.moved) for r in results]),
        ("robot failures", [str(r.robot_failures) for r in results]),
        ("robots left", [str(r.robots_left) for r in results]),
        ("robot errors", [str(len(r.errors)) for r in results]),
    ]
    for label, cells in rows:
        head.add_row(Text(label), *cells)  # Text: '[s]' is a unit, not rich markup
    parts: list[Any] = [head]
    for r in results:
        for e in r.errors:
            parts.append(Text(f"{r.scenario}: {e.robot} at {e.time:.0f} s: {e.error}", "red"))
        if r.timed_out:
            parts.append(Text(f"{r.scenario}: stopped at its time limit", "red"))
        if r.interrupted:
            parts.append(Text(f"{r.scenario}: interrupted before the end", "red"))
    for r in results:
        t = Table(title=f"{r.scenario}: robots")
        for col in ("robot", "model", "utilisation", "tasks", "distance [m]"):
            right = col in ("utilisation", "distance [m]")
            t.add_column(Text(col), justify="right" if right else "left")
        for name, st in r.robots.items():
            tasks = ", ".join(f"{k} {v}" for k, v in sorted(st.tasks.items())) or "-"
            t.add_row(name, st.model, f"{100 * st.utilisation:.0f}%", tasks, f"{st.distance_m:.0f}")
        parts.append(t)
    return Group(*parts)
